"""LOD weights (paper III.D, eqs 7-11) at hand-picked distances, and block frustum culling."""

import math

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.frame import BLADES, CARDS, needs
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.lod import Camera, lod_weights


def row_layout(**lod):
    """16 x 16 cells of 1 m in 4 x 4 blocks; blade counts num = 4; bands 2-4 m and 6-10 m."""
    values = {"field.blocks_x": 4, "field.blocks_y": 4, "field.cells_per_block": 4, "field.cell_size": 1.0,
              "field.blades_per_cell": 4, "lod.blade_near": 2.0, "lod.blade_far": 4.0,
              "lod.card_near": 6.0, "lod.card_far": 10.0}
    values.update({f"lod.{k}": v for k, v in lod.items()})
    return build_layout(schema.defaults().replace(values))


def eye_over_cell0(layout, height=3.0):
    x, y = layout.cell_center[0]
    return Camera.look_at((x, y, height), (x + 10.0, y, 0.0), math.radians(60.0), 1.5)


def test_weights_follow_eqs_7_to_11_at_chosen_distances():
    layout = row_layout()
    w = lod_weights(layout, eye_over_cell0(layout), layout.params)
    # Cells 0, 4, 8, 12 lie 0, 4, 8, 12 m along +X from the eye's ground point; the eye is 3 m up,
    # so d = 3, 5, sqrt(73) = 8.544, sqrt(153) = 12.369 m.
    cells = [0, 4, 8, 12]
    # eq 7, K_b = (d - 2) / 2 clamped: 0.5, 1, 1, 1; eq 8, K_g = 1 - K_b.
    np.testing.assert_allclose(w.k_geometry[cells], [0.5, 0.0, 0.0, 0.0], atol=1e-6)
    # eq 9, N = floor(4 K_g): 2, 0, 0, 0
    np.testing.assert_array_equal(w.blade_count[cells], [2, 0, 0, 0])
    # eq 10, K_t = (d - 6) / 4 clamped: 0, 0, 0.636, 1
    np.testing.assert_allclose(w.k_texture[cells], [0.0, 0.0, (math.sqrt(73) - 6) / 4, 1.0], atol=1e-6)
    # card opacity: K_b in the first band, 1 between bands, K'_b = 1 - K_t (eq 11) in the second
    np.testing.assert_allclose(w.k_billboard[cells], [0.5, 1.0, 1.0 - (math.sqrt(73) - 6) / 4, 0.0], atol=1e-6)
    # a cell at d = sqrt(1 + 9) = 3.162 m: K_g = 1 - 0.581 = 0.419, N = floor(1.675) = 1
    assert w.blade_count[1] == 1
    np.testing.assert_allclose(w.k_geometry[1], 1 - (math.sqrt(10) - 2) / 2, atol=1e-6)
    assert w.k_geometry.dtype == np.float32 and w.blade_count.dtype == np.int32
    assert w.k_geometry.shape == (layout.n_cells,)


def test_blades_near_the_eye_are_all_geometry():
    layout = row_layout()
    w = lod_weights(layout, eye_over_cell0(layout, height=1.0), layout.params)
    assert w.blade_count[0] == 4 and w.k_geometry[0] == 1.0 and w.k_billboard[0] == 0.0  # d = 1 < d_g1


def test_zero_width_band_is_a_step():
    layout = row_layout(blade_near=3.5, blade_far=3.5)
    w = lod_weights(layout, eye_over_cell0(layout), layout.params)
    np.testing.assert_array_equal(w.blade_count[[0, 4]], [4, 0])  # d = 3 before the step, 5 after
    np.testing.assert_array_equal(w.k_billboard[[0, 4]], [0.0, 1.0])


def test_no_camera_or_lod_off_means_all_geometry():
    layout = row_layout()
    off = layout.params.replace({"lod.enabled": False})
    for w in (lod_weights(layout, None, layout.params), lod_weights(layout, eye_over_cell0(layout), off)):
        assert np.all(w.k_geometry == 1.0) and np.all(w.k_billboard == 0.0) and np.all(w.k_texture == 0.0)
        assert np.all(w.blade_count == 4) and w.block_visible.all()


def test_frustum_culling_drops_blocks_behind_the_camera():
    """Eye at the field centre, 1.5 m up, looking along +X with a 60 degree view: blocks whose
    whole box lies at x < 0 (behind the eye) are culled; blocks ahead within the view are kept."""
    layout = row_layout()
    cam = Camera.look_at((0.0, 0.0, 1.5), (10.0, 0.0, 1.5), math.radians(60.0), 1.5)
    w = lod_weights(layout, cam, layout.params)
    b = layout.block_bounds  # blocks are 4 m wide: x in [-8, -4], [-4, 0], [0, 4], [4, 8]
    behind = b[:, 2] <= -1.0  # more than a blade (or card) reach behind the eye: the x in [-8, -4] column
    ahead = (b[:, 0] >= 0.0) & (np.abs(b[:, 1] + b[:, 3]) / 2 < 4.0)
    assert behind.sum() == 4 and not w.block_visible[behind].any()
    assert ahead.sum() == 4 and w.block_visible[ahead].all()
    # Looking the other way swaps them.
    back = lod_weights(layout, Camera.look_at((0, 0, 1.5), (-10, 0, 1.5), math.radians(60.0), 1.5), layout.params)
    assert back.block_visible[behind & (np.abs(b[:, 1] + b[:, 3]) / 2 < 4.0)].all()
    assert not back.block_visible[b[:, 0] >= 1.0].any()


def test_block_distance_is_to_the_nearest_point():
    layout = row_layout()
    cam = Camera.look_at((0.5, 0.5, 2.0), (10.0, 0.5, 0.0), math.radians(60.0), 1.5)
    w = lod_weights(layout, cam, layout.params)
    b = layout.block_bounds
    inside = (b[:, 0] <= 0.5) & (b[:, 2] >= 0.5) & (b[:, 1] <= 0.5) & (b[:, 3] >= 0.5)
    np.testing.assert_allclose(w.block_distance[inside], 2.0)  # straight down
    far = np.argmax((b[:, 0] == 4.0) & (b[:, 1] == 0.0))  # block x in [4, 8], y in [0, 4]
    np.testing.assert_allclose(w.block_distance[far], math.sqrt(3.5 ** 2 + 2.0 ** 2), rtol=1e-6)


def test_bad_camera_names_the_problem():
    layout = row_layout()
    with pytest.raises(schema.ParameterError, match="camera"):
        lod_weights(layout, Camera.look_at((0, 0, 1), (0, 0, 1), 1.0), layout.params)


# --------------------------------------------------------------------------------------------
# The real view: lens shift, orthographic and panoramic cameras, several views at once


def _point_boxes(points):
    """Blocks of zero size at ground points (bounds (m, 4), z range (m, 2)) and params whose
    blades and cards reach 1 mm: the culling test then asks about the points themselves."""
    p = schema.defaults().replace({"blade.species": [{"length": 0.01, "length_variation": 0.0}],
                                   "lod.card_height": 0.05, "lod.card_width": 0.1, "field.cell_size": 0.01})
    pts = np.asarray(points, dtype=np.float64)
    bounds = np.stack([pts[:, 0], pts[:, 1], pts[:, 0], pts[:, 1]], axis=1)
    return bounds, np.zeros((len(pts), 2)), p


def _projected_inside(cam, points, margin):
    """Independent of lod.py: project ground points through the camera (Blender's conventions) and
    say which land inside the image shrunk (margin < 0) or grown (margin > 0) by ``margin``
    (a fraction of the image's half-width)."""
    f = np.asarray(cam.forward, float) / np.linalg.norm(cam.forward)
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    rel = np.asarray(points, float) - np.asarray(cam.position, float)
    x, y, z = rel @ r, rel @ u, rel @ f
    if cam.projection == "ORTHO":
        tx = cam.ortho_width / 2
        sx, sy = x, y
    else:
        tx = math.tan(cam.fov_x / 2)
        sx, sy = x / np.maximum(z, 1e-12), y / np.maximum(z, 1e-12)
    ty = tx / cam.aspect
    big = max(tx, ty)
    cx, cy = 2 * cam.shift[0] * big, 2 * cam.shift[1] * big
    ok = (np.abs(sx - cx) <= tx * (1 + margin)) & (np.abs(sy - cy) <= ty * (1 + margin)) & (z > 0)
    return ok


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.6, 0.0), (-0.3, 0.25)])
def test_culling_follows_the_lens_shift(shift):
    """Issue: with shift_x = 0.6 the shifted part of the image showed bare ground. Every ground
    point that projects into the shifted image is kept; points well outside it are culled."""
    from windgrass.grass_addon.lod import block_visible

    rng = np.random.default_rng(3)
    points = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-40, 40, 4000), np.zeros(4000)])
    cam = Camera((0.0, -20.0, 6.0), (0.0, 1.0, -0.25), (0.0, 0.0, 1.0), math.radians(50.0), 16 / 9, shift=shift)
    bounds, z, params = _point_boxes(points)
    seen = block_visible(bounds, z, cam, params)
    assert seen[_projected_inside(cam, points, -0.02)].all()
    assert not seen[~_projected_inside(cam, points, 0.05)].any()
    if shift[0] > 0.5:  # the right edge of the shifted image lies past the unshifted one's
        plain = Camera(cam.position, cam.forward, cam.up, cam.fov_x, cam.aspect)
        assert (seen & ~block_visible(bounds, z, plain, params)).sum() > 100


def test_culling_of_an_orthographic_view():
    from windgrass.grass_addon.lod import block_visible

    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-40, 40, 4000), rng.uniform(-40, 40, 4000), np.zeros(4000)])
    cam = Camera((5.0, -30.0, 20.0), (0.0, 1.0, -0.7), (0.0, 0.0, 1.0), 0.0, 1.5, projection="ORTHO",
                 ortho_width=30.0, shift=(0.2, 0.0))
    bounds, z, params = _point_boxes(points)
    seen = block_visible(bounds, z, cam, params)
    assert seen[_projected_inside(cam, points, -0.02)].all()
    assert not seen[~_projected_inside(cam, points, 0.05)].any()


def test_a_panoramic_camera_sees_every_direction():
    """Issue: an equirectangular camera showed grass only in the ~40 degrees ahead."""
    layout = row_layout()
    cam = Camera.look_at((0.0, 0.0, 1.5), (10.0, 0.0, 1.5), math.radians(60.0), 2.0)
    pano = Camera(cam.position, cam.forward, cam.up, cam.fov_x, cam.aspect, projection="PANO")
    assert not lod_weights(layout, cam, layout.params).block_visible.all()
    assert lod_weights(layout, pano, layout.params).block_visible.all()


def test_several_views_take_the_nearest_eye_and_any_view():
    """Two 3D views at opposite corners: each cell's distance is to the nearer eye (blades near
    both), a block is visible when either view sees it."""
    layout = row_layout()
    a = Camera.look_at((-7.5, -7.5, 1.0), (0.0, 0.0, 0.0), math.radians(60.0), 1.5)
    b = Camera.look_at((7.5, 7.5, 1.0), (0.0, 0.0, 0.0), math.radians(60.0), 1.5)
    wa, wb, both = (lod_weights(layout, c, layout.params) for c in (a, b, [a, b]))
    np.testing.assert_array_equal(both.blade_count, np.maximum(wa.blade_count, wb.blade_count))
    np.testing.assert_array_equal(both.block_visible, wa.block_visible | wb.block_visible)
    np.testing.assert_array_equal(both.block_distance, np.minimum(wa.block_distance, wb.block_distance))
    assert both.blade_count[0] == 4 and both.blade_count[-1] == 4  # under either eye: full blades
    assert wa.blade_count[-1] == 0 and wb.blade_count[0] == 0


@pytest.mark.slow
def test_a_camera_that_sees_no_block_simulates_nothing():
    """Issue: a field over 262,144 cells whose camera sees none of its blocks (looking at the
    sky) failed with IndexError in the solver. An empty window simulates nothing and draws
    nothing."""
    from windgrass.grass_addon.field import GrassField

    field = GrassField(schema.defaults().replace({"field.blocks_x": 300, "field.blocks_y": 300}))
    sky = Camera.look_at((0.0, 0.0, 1.0), (0.0, 0.0, 100.0), 1.0)
    cells = field.seek(5, sky)
    lod = field.lod(sky)
    assert field.layout.n_blocks == 0 and cells.bend.shape[0] == 0
    assert not needs(BLADES, field.layout, lod).any() and not needs(CARDS, field.layout, lod).any()
    assert field.blade_vertices(np.flatnonzero(needs(BLADES, field.layout, lod)), lod).shape == (0, 3)
    # turning to the grass fills the window again
    field.seek(6, Camera.look_at((0.0, 0.0, 1.6), (10.0, 0.0, 0.0), 1.0))
    assert field.layout.n_blocks > 0


def test_the_distances_scale_with_how_large_a_blade_is_on_screen():
    """A blade is as large on screen at distance k d in an image of k times the focal length in
    pixels: the LOD distances are the settings' for a 960-pixel image at 55 degrees (or less), k
    times them for a wider image or a longer lens, up to 4 times; an orthographic view, an
    unknown width or the setting off keeps them."""
    from windgrass.grass_addon.lod import screen_scale

    params = schema.defaults()
    fov = math.radians(55.0)

    def at(pixels, lens=fov, **kw):
        return screen_scale(Camera.look_at((0, 0, 1), (5, 0, 0), lens, pixels=pixels, **kw), params)

    assert at(960) == pytest.approx(1.0) and at(400) == 1.0 and at(0) == 1.0
    assert at(1920) == pytest.approx(2.0) and at(3840) == pytest.approx(4.0) and at(7680) == 4.0
    # a 20 degree lens at 960 pixels: tan(27.5) / tan(10) times the focal length
    assert at(960, math.radians(20.0)) == pytest.approx(math.tan(math.radians(27.5)) / math.tan(math.radians(10.0)))
    ortho = Camera(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), 0.0, 1.5, projection="ORTHO",
                   ortho_width=10.0, pixels=3840)
    assert screen_scale(ortho, params) == 1.0
    assert screen_scale(Camera.look_at((0, 0, 1), (5, 0, 0), fov, pixels=3840),
                        params.replace({"lod.screen_size": False})) == 1.0
    # the weights at k: cell 8 (8.544 m) is geometry at k = 2.5 (bands 5-10 m), not at k = 1
    layout = row_layout()
    cam = eye_over_cell0(layout)
    assert lod_weights(layout, cam, layout.params).blade_count[8] == 0
    assert lod_weights(layout, cam, layout.params, 2.5).blade_count[8] == 1  # floor(4 (1 - 3.544 / 5))


def test_a_4k_frame_draws_blades_further_out_within_the_pools():
    """The default field seen at eye level: a 1920-pixel frame draws blades to twice the distance
    of a 960-pixel one (the pools hold them); a 3840-pixel one would need four times, more than
    the pools hold: the scale is lowered until every block that needs blades or cards has a
    position in its pool, so no block is left with neither."""
    from windgrass.grass_addon.field import GrassField

    params = schema.defaults().replace({"field.blocks_x": 64, "field.blocks_y": 64})
    field = GrassField(params)

    def frame(pixels):
        cam = Camera.look_at((0.0, 0.0, 1.2), (20.0, 0.0, 0.0), math.radians(55.0), pixels=pixels)
        shown = field.frame(1, views=cam)
        lod = shown.lod
        wanted = [int(needs(role, field.layout, lod).sum()) for role in (BLADES, CARDS)]
        far = lod.block_distance[(lod.blade_count[field.layout.block_cells] > 0).any(axis=1)].max()
        return lod.scale, wanted, [shown.blades.count, shown.cards.count], far

    s1, want1, got1, far1 = frame(960)
    s2, want2, got2, far2 = frame(1920)
    s4, want4, got4, far4 = frame(3840)
    assert s1 == 1.0 and s2 == pytest.approx(2.0) and 2.0 < s4 < 4.0
    assert far1 < params.lod.blade_far < far2 < 2 * params.lod.blade_far and far4 > 1.2 * far2
    assert want2[0] > 2 * want1[0] and got2 == want2 and got4 == want4
    positions = [field.shapes[role].positions for role in (BLADES, CARDS)]
    assert all(w <= p for w, p in zip(want4, positions))
