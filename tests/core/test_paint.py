"""Painted grass (paint.py, blocks.make_block): maps of density, length and species, keep-out shapes.

Each blade draws its own numbers once; paint only decides, where it stands, whether it grows, how
long it is and which species it is. The checks count blade roots against what was painted.
"""

import math

import numpy as np
import pytest
from windgrass.grass_addon import blade, schema
from windgrass.grass_addon.blocks import BlockCache
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.lod import Camera
from windgrass.grass_addon.paint import KeepOut, Paint, Raster, box_triangles, disc_triangles

# 8 x 8 blocks of 8 x 8 cells of 0.1 m: a 6.4 m field, 4 blades a cell (16,384 blades)
PARAMS = schema.defaults().replace({"field.blocks_x": 8, "field.blocks_y": 8, "field.cells_per_block": 8,
                                    "field.blades_per_cell": 4})
HALF = 3.2
EXTENT = (-HALF, -HALF, HALF, HALF)


def layout_of(paint, params=PARAMS):
    return build_layout(params, cache=BlockCache(params, paint=paint, budget=1 << 40))


def grown(layout):
    alive = layout.blade_alive if layout.blade_alive is not None else np.ones(layout.n_blades, bool)
    return layout.blade_root[alive]


def test_without_paint_the_field_is_the_same_bits():
    plain, empty = layout_of(None), layout_of(Paint())
    assert empty.blade_alive is None
    for name in ("blade_root", "blade_length", "blade_species", "blade_rest_tilt", "card_height"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(empty, name))


def test_a_stripe_painted_out_has_no_blade_and_the_rest_all_of_them():
    """Density 0 in a stripe 1.2 m wide across the field (x in [-0.6, 0.6]), 1 elsewhere."""
    pixels = np.ones((64, 64), np.float32)
    xs = (np.arange(64) + 0.5) / 64 * 6.4 - 3.2
    pixels[:, np.abs(xs) < 0.6] = 0.0
    layout = layout_of(Paint(density=Raster(pixels, EXTENT)))
    roots = grown(layout)
    assert not np.any(np.abs(roots[:, 0]) < 0.55)  # half a pixel inside the painted edge: none grows
    far = np.abs(layout.blade_root[:, 0]) > 0.65
    assert layout.blade_alive[far].all()  # outside the stripe every blade grows
    # the cells in the stripe show no card, the others full ones
    x = layout.cell_center[:, 0]
    assert np.all(layout.cell_density[np.abs(x) < 0.5] == 0.0) and np.all(layout.cell_density[np.abs(x) > 0.7] == 1.0)


def test_a_density_gradient_grows_the_painted_share_per_band():
    """Density rising linearly from 0 at the west edge to 1 at the east: in each of 8 bands the
    share of blades that grow is the band's mean density, within 3 points (8 blades a cell, 4,096
    a band: the binomial error of a band is at most 0.8 points; over 6 seeds the bands' errors
    measured a mean of 0.2 and a spread of 0.99 standard errors: no bias)."""
    pixels = np.tile(((np.arange(256) + 0.5) / 256).astype(np.float32), (4, 1))
    layout = layout_of(Paint(density=Raster(pixels, EXTENT)), PARAMS.replace({"field.blades_per_cell": 8}))
    x = layout.blade_root[:, 0].astype(np.float64)
    edges = np.linspace(-HALF, HALF, 9)
    for lo, hi in zip(edges[:-1], edges[1:]):
        band = (x >= lo) & (x < hi)
        expected = ((x[band] + HALF) / (2 * HALF)).mean()
        assert layout.blade_alive[band].mean() == pytest.approx(expected, abs=0.03), (lo, hi)


def test_painting_more_grass_adds_blades_and_moves_none():
    """Raising the density in one patch: every blade that grew still grows, at the same place,
    length and shape, bit for bit; new ones appear only in the patch."""
    low = np.full((32, 32), 0.3, np.float32)
    more = low.copy()
    more[8:16, 8:16] = 0.9
    a, b = layout_of(Paint(density=Raster(low, EXTENT))), layout_of(Paint(density=Raster(more, EXTENT)))
    assert np.all(b.blade_alive[a.blade_alive])  # nothing that grew is gone
    for name in ("blade_root", "blade_length", "blade_facing", "blade_species", "blade_rest_tilt", "blade_width"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    new = b.blade_alive & ~a.blade_alive
    assert new.sum() > 500
    u, v = ((b.blade_root[new, :2] + HALF) / (2 * HALF) * 32).T
    assert np.all((u > 7) & (u < 17) & (v > 7) & (v < 17))  # within the patch (and its bilinear edge)


def test_a_length_map_scales_the_blades_and_their_rest_tips():
    """Length 0.5 (grey 0.25 of the 0..2 range) on the west half, 1 (grey 0.5) on the east: the
    blades there are exactly half as long; their rest tips stand lower, about half as high (a
    shorter blade droops less, so a little more than half)."""
    pixels = np.full((16, 16), 0.5, np.float32)
    pixels[:, :8] = 0.25
    plain, painted = layout_of(None), layout_of(Paint(length=Raster(pixels, EXTENT)))
    west = painted.blade_root[:, 0] < -0.5
    east = painted.blade_root[:, 0] > 0.5
    np.testing.assert_allclose(painted.blade_length[west], 0.5 * plain.blade_length[west], rtol=1e-6)
    np.testing.assert_array_equal(painted.blade_length[east], plain.blade_length[east])
    tips_plain = blade.tip_height(plain.blade_length[west], plain.blade_rest_tilt[west])
    tips = blade.tip_height(painted.blade_length[west], painted.blade_rest_tilt[west])
    ratio = float(np.median(tips / tips_plain))
    assert 0.5 <= ratio < 0.6, ratio
    assert painted.blade_alive.all()  # a length map alone removes no blade


def test_keep_out_shapes_remove_the_grass_around_them():
    """A box (1 x 2 m, turned 30 degrees) and a disc (radius 0.8 m) with a 0.2 m margin and a
    0.3 m falloff: no root within footprint + margin, every blade beyond footprint + margin +
    falloff, and in between a share that rises with the distance."""
    box = box_triangles((-1.5, 0.0), (1.0, 2.0), 30.0)
    disc = disc_triangles((1.5, 0.5), 0.8)
    keep = KeepOut(np.concatenate([box, disc]), margin=0.2, falloff=0.3)
    layout = layout_of(Paint(keep_out=keep))
    xy = layout.blade_root[:, :2].astype(np.float64)
    # distance to the shapes, computed here from their definitions
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    local = (xy - (-1.5, 0.0)) @ np.array([[c, -s], [s, c]])
    out = np.maximum(np.abs(local) - (0.5, 1.0), 0.0)
    d_box = np.hypot(out[:, 0], out[:, 1])
    d_disc = np.maximum(np.hypot(xy[:, 0] - 1.5, xy[:, 1] - 0.5) - 0.8, 0.0)
    d = np.minimum(d_box, d_disc)
    assert not layout.blade_alive[d < 0.2 - 1e-3].any()
    assert layout.blade_alive[d > 0.5 + 1e-3].all()
    ring = (d > 0.2) & (d < 0.5)
    near, far = ring & (d < 0.35), ring & (d >= 0.35)
    assert 0.0 < layout.blade_alive[near].mean() < layout.blade_alive[far].mean() < 1.0


def test_species_maps_plant_each_species_where_painted():
    """Two species; the first's map is 1 on the north half and 0 on the south: the south grows only
    the second, the north both (by their shares); the blades' own numbers pick them."""
    params = PARAMS.replace({"blade.species": [{"name": "a", "weight": 1.0}, {"name": "b", "weight": 1.0}]})
    north = np.zeros((16, 16), np.float32)
    north[8:] = 1.0
    layout = layout_of(Paint(species=(Raster(north, EXTENT), None)), params)
    y = layout.blade_root[:, 1]
    assert np.all(layout.blade_species[y < -0.3] == 1)
    top = layout.blade_species[y > 0.3]
    assert 0.4 < (top == 0).mean() < 0.6
    plain = layout_of(None, params)
    np.testing.assert_array_equal(layout.blade_species[y > 0.3], plain.blade_species[y > 0.3])  # the same picks


@pytest.mark.slow  # (many seconds: dev.py test --quick leaves it out)
def test_blocks_painted_out_are_not_simulated_and_frames_stay_addressable():
    """A 1 km field (not simulated whole) with its west half painted out: the window holds only
    blocks where grass grows; frame 40 reached directly equals frame 40 after 1-39 (paint is part
    of what a block is a function of)."""
    params = schema.defaults().replace({"field.blocks_x": 100, "field.blocks_y": 100})
    west = np.ones((8, 64), np.float32)  # pixels 2.5 m wide
    west[:, :32] = 0.0
    paint = Paint(density=Raster(west, (-80.0, -80.0, 80.0, 80.0)))
    cam = Camera.look_at((0.0, -10.0, 1.7), (0.0, 10.0, 0.0), math.radians(70.0))
    direct = GrassField(params, paint=paint)
    cells = direct.seek(40, cam)
    bounds = direct.layout.block_bounds
    assert np.all(bounds[:, 2] > -1.25)  # no block wholly west of the last 0 pixel's centre
    plain = GrassField(params)
    plain.seek(40, cam)
    assert direct.layout.n_blocks < 0.6 * plain.layout.n_blocks  # about half the cells to simulate
    stepped = GrassField(params, paint=paint)
    for frame in range(1, 41):
        stepped.seek(frame, cam)
    np.testing.assert_array_equal(stepped.sim.state.bend_t, direct.sim.state.bend_t)
    assert cells.bend.shape[0] == direct.layout.n_cells


@pytest.mark.parametrize("bad, key", [
    (lambda: Raster(np.ones((4, 4)), (1.0, 0.0, 0.0, 1.0)), "map"),
    (lambda: Raster(np.full((4, 4), np.nan), EXTENT), "map"),
    (lambda: Raster(np.ones(4), EXTENT), "map"),
])
def test_bad_maps_are_named(bad, key):
    with pytest.raises(schema.ParameterError) as info:
        bad()
    assert info.value.key == key


# --------------------------------------------------------------------------------------------
# Scene files: maps and heightmaps as PNG files, paths from the scene file's folder


def test_a_scene_file_paints_with_png_maps_next_to_it(tmp_path):
    """[paint] density = "stripe.png" (relative to the scene file), [[keep_out.shapes]] a disc:
    blades grow as painted; simulate.py's numpy path reads the same files."""
    from windgrass.grass_addon import images

    stripe = np.ones((64, 64))
    stripe[:, 28:36] = 0.0  # x in [-0.4, 0.4] of the 6.4 m field
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "stripe.png").write_bytes(images.encode_png(stripe))
    (tmp_path / "scene.toml").write_text(
        "[field]\nblocks_x = 8\nblocks_y = 8\ncells_per_block = 8\nblades_per_cell = 4\n"
        '[paint]\ndensity = "maps/stripe.png"\n'
        "[keep_out]\nmargin = 0.0\nfalloff = 0.0\n"
        '[[keep_out.shapes]]\nshape = "disc"\ncenter = [2.0, 2.0]\nradius = 0.5\n')
    params = schema.load_toml(tmp_path / "scene.toml")
    assert params.paint.density == str(tmp_path / "maps" / "stripe.png")
    field = GrassField.of_scene(params)
    layout = field.layout
    x, y = layout.blade_root[:, 0], layout.blade_root[:, 1]
    assert not layout.blade_alive[np.abs(x) < 0.35].any()
    assert not layout.blade_alive[np.hypot(x - 2.0, y - 2.0) < 0.5].any()
    assert layout.blade_alive[(np.abs(x) > 0.5) & (np.hypot(x - 2.0, y - 2.0) > 0.55)].all()


def test_a_heightmap_roots_every_blade_on_its_surface(tmp_path):
    """[terrain] heightmap: a ramp from black (west) to white (east), height 2 m: every blade root
    and cell lies on the surface the image describes (z = 2 (x - x0) / width, between pixel
    centres)."""
    from windgrass.grass_addon import images

    ramp = np.tile((np.arange(256) + 0.5) / 256, (8, 1))
    (tmp_path / "ramp.png").write_bytes(images.encode_png(ramp))
    (tmp_path / "hills.toml").write_text("[field]\nblocks_x = 4\nblocks_y = 4\ncells_per_block = 8\n"
                                         '[terrain]\nheightmap = "ramp.png"\nheight = 2.0\n')
    field = GrassField.of_scene(schema.load_toml(tmp_path / "hills.toml"))
    layout = field.layout
    x = layout.blade_root[:, 0].astype(np.float64)
    expected = 2.0 * (x + 1.6) / 3.2
    np.testing.assert_allclose(layout.blade_root[:, 2], expected, atol=2.0 / 255 + 1e-3)  # 8-bit steps
    assert layout.terrain is not None and layout.blade_ground_slope is not None


@pytest.mark.parametrize("toml, key, words", [
    ('[paint]\ndensity = "missing.png"\n', "paint.density", ["missing.png", "does not exist"]),
    ('[paint]\ndensity = "scene.toml"\n', "paint.density", ["not an image"]),
    ('[paint]\ndensity = "ok.png"\nextent = [2.0, 0.0, 1.0, 1.0]\n', "paint.extent", ["x1 > x0"]),
    ('[terrain]\nheightmap = "nowhere.png"\n', "terrain.heightmap", ["does not exist"]),
    ('[[keep_out.shapes]]\nshape = "box"\nsize = [0.0, 1.0]\n', "keep_out.shapes[0].size", ["> 0"]),
    ('[[keep_out.shapes]]\nshape = "star"\n', "keep_out.shapes[0].shape", ["box", "disc"]),
])
def test_bad_maps_in_scene_files_name_the_setting(tmp_path, toml, key, words):
    from windgrass.grass_addon import images

    (tmp_path / "ok.png").write_bytes(images.encode_png(np.ones((4, 4))))
    (tmp_path / "scene.toml").write_text(toml)
    with pytest.raises(schema.ParameterError) as info:
        GrassField.of_scene(schema.load_toml(tmp_path / "scene.toml"))
    assert info.value.key == key
    for word in words:
        assert word in str(info.value)


def _states_by_block(field):
    """{block id: (bend, twist) of its cells} of a field's shown state."""
    st, layout = field.sim.state, field.layout
    out = {}
    for i, b in enumerate(layout.block_ids.tolist()):
        cols = layout.block_cells[i]
        out[b] = (st.bend_t[..., cols].copy(), st.twist_t[..., cols].copy())
    return out


@pytest.mark.slow  # (many seconds: dev.py test --quick leaves it out)
def test_a_stroke_makes_again_only_the_blocks_it_touches_and_gives_what_a_fresh_field_gives():
    """Painting a patch near the camera of a 1 km field (a mown square, length 0.5, and a bare
    strip): only the blocks under the stroke are made again, and the frame equals, bit for bit,
    that of a field made with the new paint from the start (the cells whose blades got shorter
    were simulated again)."""
    params = schema.defaults().replace({"field.blocks_x": 100, "field.blocks_y": 100})
    cam = Camera.look_at((0.0, -6.0, 1.7), (0.0, 10.0, 0.0), math.radians(60.0))
    before = np.full((160, 160), 0.5, np.float32)  # 1 m pixels over the middle 160 m; length 1
    extent = (-80.0, -80.0, 80.0, 80.0)
    full = np.ones((160, 160), np.float32)
    field = GrassField(params, paint=Paint(length=Raster(before, extent), density=Raster(full, extent)))
    field.seek(30, cam)
    window = field.layout.n_blocks
    after = before.copy()
    after[82:86, 78:84] = 0.25  # mown: 4 m x 6 m, a few metres ahead of the camera
    density = full.copy()
    density[80:82, 70:90] = 0.0  # a bare strip
    paint = Paint(length=Raster(after, extent), density=Raster(density, extent))
    made = field.repaint(paint, frame=30)
    assert 0 < made < 0.2 * window  # the blocks under the stroke (and the cache around them), not the window
    field.seek(30, cam)
    fresh = GrassField(params, paint=paint)
    fresh.seek(30, cam)
    mine, theirs = _states_by_block(field), _states_by_block(fresh)
    common = set(mine) & set(theirs)
    assert len(common) > 0.9 * len(theirs)
    for b in common:
        np.testing.assert_array_equal(mine[b][0], theirs[b][0], err_msg=str(b))
        np.testing.assert_array_equal(mine[b][1], theirs[b][1], err_msg=str(b))
