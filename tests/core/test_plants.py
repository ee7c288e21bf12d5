"""The artist's own plants on the cards (``plants.py``): a plant splatted onto a card covers what
its triangles cover, seen from the side, on its stem's rest centre line, across the card's seam."""

import numpy as np
from windgrass.grass_addon import plants

SIZE = 128


def _square(half: float = 0.5):
    """A plant 1 m tall and 2 * half wide in x (two triangles), 0.5 m of it in y too, coloured red."""
    points = [(-half, 0.0, 0.0), (half, 0.0, 0.0), (half, 0.0, 1.0), (-half, 0.0, 1.0)]
    return plants.PlantShape.of(points, [(0, 1, 2), (0, 2, 3)], [(1.0, 0.0, 0.0)] * 2)


def _draw(shape, u_root, across, along, up, scale_u):
    rgb, alpha = np.zeros((SIZE, SIZE, 3)), np.zeros((SIZE, SIZE))
    plants.draw(rgb, alpha, shape, u_root, across, np.asarray(along, float), np.asarray(up, float), scale_u)
    return rgb, alpha


def _box(u0, u1, v0, v1):
    xs = (np.arange(SIZE) + 0.5) / SIZE
    return ((xs[None, :] > u0) & (xs[None, :] < u1)) & ((xs[:, None] > v0) & (xs[:, None] < v1))


def test_an_upright_plant_covers_its_side_view_and_nothing_else():
    """A 1 x 1 plant on an upright stem reaching half the card's height, a quarter of its width
    long, at u = 0.5: covered, in its colour, exactly over u 0.375-0.625, v 0-0.5 (one pixel's
    edge either way); no pixel beyond."""
    rgb, alpha = _draw(_square(), 0.5, (1.0, 0.0), [0.0, 0.0], [0.0, 0.5], 0.25)
    px = 1 / SIZE
    inner, outer = _box(0.375 + px, 0.625 - px, px, 0.5 - px), _box(0.375 - px, 0.625 + px, -1, 0.5 + px)
    assert (alpha[inner] == 1.0).all() and (rgb[inner] == (1.0, 0.0, 0.0)).all()
    assert (alpha[~outer] == 0.0).all()


def test_a_plant_follows_its_stems_lean_and_its_turn():
    """On a stem leaning 0.2 of the card across over its height, the plant's top row sits 0.2
    further across than its foot; turned edge on (across (0, 1): the plant's y, which it has
    none of), it is a line a pixel or two wide."""
    _, alpha = _draw(_square(0.1), 0.5, (1.0, 0.0), [0.0, 0.2], [0.0, 0.5], 0.25)
    xs = (np.arange(SIZE) + 0.5) / SIZE
    foot, top = alpha[1], alpha[int(0.5 * SIZE) - 2]
    shift = xs[top > 0].mean() - xs[foot > 0].mean()
    assert abs(shift - 0.2 * (0.5 - 2 / SIZE) / 0.5) < 2 / SIZE, shift
    _, edge_on = _draw(_square(0.5), 0.5, (0.0, 1.0), [0.0, 0.0], [0.0, 0.5], 0.25)
    assert 0 < edge_on.sum(axis=1).max() <= 2


def test_what_leaves_one_edge_of_the_card_comes_in_at_the_other():
    """A plant at the card's edge (u = 0) covers the same area as one in its middle: half of it
    wraps round to u near 1, as a blade's strip does."""
    _, middle = _draw(_square(), 0.5, (1.0, 0.0), [0.0, 0.0], [0.0, 0.5], 0.25)
    _, edge = _draw(_square(), 0.0, (1.0, 0.0), [0.0, 0.0], [0.0, 0.5], 0.25)
    assert abs(edge.sum() - middle.sum()) <= 2 * 0.5 * SIZE and edge[:, -3:].any() and edge[:, :3].any()


def test_the_plants_are_known_by_their_contents():
    """Plants are kept by a digest of their triangles and colours (the atlas is remembered by it):
    the same shapes give the same key, a moved vertex another."""
    a, b = plants.Plants(((0, _square()),)), plants.Plants(((0, _square()),))
    assert repr(a) == repr(b) and repr(a) != repr(plants.Plants(((0, _square(0.4)),)))
    assert not plants.Plants() and a.of_species(0) is not None and a.of_species(1) is None


def test_the_far_grass_shows_a_plants_colour_weighed_by_area():
    """A plant of a red triangle and a green one three times its area is seen from afar as a
    quarter red, three quarters green; ``seen_far`` gives that colour to the plant's species alone."""
    from windgrass.grass_addon import schema

    points = [(0, 0, 0), (1, 0, 0), (0, 0, 1), (0, 0, 0), (3, 0, 0), (0, 0, 1)]
    shape = plants.PlantShape.of(points, [(0, 1, 2), (3, 4, 5)], [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])
    np.testing.assert_allclose(shape.mean_colour(), (0.25, 0.75, 0.0))
    params = schema.defaults().replace({"blade.species": [{"name": "a"}, {"name": "b", "color": (0.1, 0.2, 0.3)}]})
    far = plants.seen_far(params, plants.Plants(((0, shape),)))
    np.testing.assert_allclose(far.species()[0]["color"], (0.25, 0.75, 0.0))
    assert tuple(far.species()[1]["color"]) == (0.1, 0.2, 0.3) and plants.seen_far(params, plants.Plants()) is params
