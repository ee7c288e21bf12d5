"""Terrain: a bilinear heightfield under the field; roots, cells, LOD and culling follow it."""

import math

import numpy as np
import pytest
from windgrass.grass_addon import schema, terrain
from windgrass.grass_addon.blade import GROUND_TILT
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.lod import Camera, lod_weights


def small_params(**extra):
    values = {"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4, "field.cell_size": 0.5,
              "field.blades_per_cell": 3}
    values.update(extra)
    return schema.defaults().replace(values)


def plane(xy, a=0.7, b=0.2, c=-0.35):
    """A tilted plane z = a + b x + c y (slopes of 11 and 19 degrees)."""
    xy = np.asarray(xy, dtype=np.float64)
    return a + b * xy[..., 0] + c * xy[..., 1]


def heightfield_of(params, func) -> terrain.Heightfield:
    origin, spacing, nx, ny = terrain.grid_for(params)
    pts = terrain.grid_points(origin, spacing, nx, ny)
    return terrain.Heightfield(origin, spacing, func(pts))


def test_bilinear_sampling_reproduces_planes_and_saddles_exactly():
    """Bilinear interpolation is exact for a + bx + cy + dxy (its four basis functions), so a tilted
    plane, and even a saddle, are reproduced to float32 precision anywhere inside the grid."""
    rng = np.random.default_rng([0, 31])
    grid = terrain.Heightfield((-2.0, -1.0), 0.25, np.zeros((9, 17)))
    pts = grid.points()
    xy = rng.uniform((-2.0, -1.0), (2.0, 1.0), (500, 2))
    for func in (plane, lambda p: 0.3 * p[..., 0] * p[..., 1] - 0.1 * p[..., 0]):
        hf = terrain.Heightfield((-2.0, -1.0), 0.25, func(pts))
        np.testing.assert_allclose(hf.sample(xy), func(xy), rtol=0, atol=4e-7 * 4)
        assert hf.sample(xy).dtype == np.float32
    # Outside the grid the edge height holds (clamped), never extrapolated.
    hf = terrain.Heightfield((-2.0, -1.0), 0.25, plane(pts))
    assert hf.sample([5.0, 0.0]) == pytest.approx(plane([2.0, 0.0]), abs=1e-6)
    assert hf.sample([-9.0, -9.0]) == pytest.approx(plane([-2.0, -1.0]), abs=1e-6)


def test_grid_covers_the_field_one_sample_per_cell_corner():
    params = small_params()
    origin, spacing, nx, ny = terrain.grid_for(params)
    assert spacing == 0.5 and (nx, ny) == (12, 8)  # 12 x 8 cells of 0.5 m
    np.testing.assert_allclose(origin, (-3.0, -2.0))  # the field is centred on the origin
    # A huge field is sampled more coarsely, but the grid still covers it.
    big = schema.defaults().replace({"field.blocks_x": 64, "field.blocks_y": 8, "field.cells_per_block": 16,
                                     "field.blades_per_cell": 0})
    origin, spacing, nx, ny = terrain.grid_for(big)
    assert nx <= terrain.MAX_GRID_CELLS and nx * spacing >= 64 * 16 * 0.1 - 1e-9
    assert ny * spacing >= 8 * 16 * 0.1 - 1e-9


def test_roots_lie_on_the_terrain_and_the_xy_layout_is_unchanged():
    params = small_params()
    hf = heightfield_of(params, plane)
    flat, hilly = build_layout(params), build_layout(params, terrain=hf)
    # Same blades in the same places seen from above; only the heights differ.
    np.testing.assert_array_equal(hilly.blade_root[:, :2], flat.blade_root[:, :2])
    np.testing.assert_array_equal(flat.blade_root[:, 2], 0.0)
    np.testing.assert_allclose(hilly.blade_root[:, 2], plane(hilly.blade_root[:, :2]), atol=2e-6)
    # cell_ground: the ground at each cell centre; zeros without a terrain.
    np.testing.assert_allclose(hilly.cell_ground, plane(hilly.cell_center), atol=2e-6)
    np.testing.assert_array_equal(flat.cell_ground, np.zeros(flat.n_cells, np.float32))
    # block_z_range holds every root of the block (culling boxes must contain the ground).
    z = hilly.blade_root[:, 2].reshape(hilly.n_blocks, -1)
    assert np.all(hilly.block_z_range[:, 0] <= z.min(axis=1) + 1e-6)
    assert np.all(hilly.block_z_range[:, 1] >= z.max(axis=1) - 1e-6)
    # For a plane the range is exactly the plane over the block's corners.
    b = hilly.block_bounds
    corners = np.stack([plane(b[:, [0, 1]]), plane(b[:, [2, 1]]), plane(b[:, [0, 3]]), plane(b[:, [2, 3]])], 1)
    np.testing.assert_allclose(hilly.block_z_range[:, 0], corners.min(axis=1), atol=2e-6)
    np.testing.assert_allclose(hilly.block_z_range[:, 1], corners.max(axis=1), atol=2e-6)
    np.testing.assert_array_equal(flat.block_z_range, 0.0)


def test_block_z_range_bounds_a_bumpy_ground():
    params = small_params(**{"field.cell_size": 0.3})
    rng = np.random.default_rng([1, 31])
    origin, spacing, nx, ny = terrain.grid_for(params, max_cells=5)  # grid coarser than the blocks
    hf = terrain.Heightfield(origin, spacing, rng.normal(0.0, 1.0, (ny + 1, nx + 1)))
    layout = build_layout(params, terrain=hf)
    for blk, (x0, y0, x1, y1) in enumerate(layout.block_bounds):
        z = hf.sample(rng.uniform((x0, y0), (x1, y1), (400, 2)))
        lo, hi = layout.block_z_range[blk]
        assert lo <= z.min() + 1e-6 and z.max() <= hi + 1e-6


def test_blade_joint_0_sits_on_the_terrain():
    """The kinematics start every strip at its root: joint 0's centre (mean of left and right) is
    on the ground, whatever the wind does to the rest of the blade. Grass on a slope still grows
    along gravity (paper III.A: the rest shape is set by gravity), so each blade is the flat
    field's blade lifted by the ground height at its root, same shape, until the slope stops it."""
    params = small_params(**{"wind.speed": 6.0})
    hilly = GrassField(params, terrain=heightfield_of(params, plane))
    flat = GrassField(params)
    shape = (hilly.layout.n_blades, params.blade.segments + 1, 2, 3)
    hilly.seek(10)
    flat.seek(10)
    v = hilly.blade_vertices(hilly.all_blocks()).reshape(shape)
    w = flat.blade_vertices(flat.all_blocks()).reshape(shape)
    root = v[:, 0].mean(axis=1)
    np.testing.assert_allclose(root[:, 2], plane(root[:, :2]), atol=1e-5)
    # The same shape as on flat ground, except where the slope stops a blade leaning into it;
    # every joint stays above the slope.
    lifted = w + root[:, None, None, :] * [0, 0, 1]
    joints = v.mean(axis=2)
    assert np.all(joints[..., 2] - plane(joints[..., :2]) >= -1e-5)
    # free: blades none of whose segments comes near lying on the flat ground or on the slope
    steps = np.diff(lifted.mean(axis=2), axis=1)
    seg = (hilly.layout.blade_length / params.blade.segments)[:, None]
    over_slope = steps[..., 2] - (plane(steps[..., :2]) - plane(np.zeros(2)))
    free = np.all((steps[..., 2] > seg * np.cos(GROUND_TILT) + 1e-3) & (over_slope > 0.05 * seg), axis=1)
    assert free.mean() > 0.8
    np.testing.assert_allclose(v[free], lifted[free], atol=2e-5)


def test_lod_distance_is_measured_to_the_cell_on_the_ground():
    """Eqs 7-11 use the eye-to-cell distance. Raising the ground and the eye by the same height
    leaves every distance, hence every weight, unchanged; on flat ground the eye height counts."""
    params = schema.defaults().replace({"field.blocks_x": 4, "field.blocks_y": 4, "field.cells_per_block": 4,
                                        "field.cell_size": 1.0, "field.blades_per_cell": 4,
                                        "lod.blade_near": 2.0, "lod.blade_far": 4.0,
                                        "lod.card_near": 6.0, "lod.card_far": 10.0})
    lift = 25.0
    raised = build_layout(params, terrain=heightfield_of(params, lambda p: np.full(p.shape[:-1], lift)))
    flat = build_layout(params)
    x, y = flat.cell_center[0]
    low = Camera.look_at((x, y, 3.0), (x + 10.0, y, 0.0), math.radians(60.0), 1.5)
    high = Camera.look_at((x, y, 3.0 + lift), (x + 10.0, y, lift), math.radians(60.0), 1.5)
    w_flat, w_raised = lod_weights(flat, low, params), lod_weights(raised, high, params)
    for name in ("k_geometry", "k_billboard", "k_texture", "blade_count"):
        np.testing.assert_allclose(getattr(w_raised, name), getattr(w_flat, name), atol=1e-5)
    np.testing.assert_allclose(w_raised.block_distance, w_flat.block_distance, atol=1e-4)
    # Cell 0 is 3 m below the eye: d = 3 m, K_b = (3 - 2) / 2 = 0.5 (eq 7), N = 2 (eq 9). Without
    # the ground height the eye would be 28 m away and see no blade at all.
    assert w_raised.k_geometry[0] == pytest.approx(0.5, abs=1e-6)
    assert w_raised.blade_count[0] == 2
    # On a slope the eye-to-cell distance is the 3-D one: z = 0.5 x, eye 1 m above cell 0.
    slope = build_layout(params, terrain=heightfield_of(params, lambda p: 0.5 * p[..., 0]))
    g0 = float(slope.cell_ground[0])
    eye = Camera.look_at((x, y, g0 + 1.0), (x + 10.0, y, g0), math.radians(60.0), 1.5)
    w = lod_weights(slope, eye, params)
    # cell 2 is 2 m along +X and 1 m higher on the ground: d = sqrt(2^2 + 0^2) = 2 -> K_b = 0
    assert float(slope.cell_ground[2]) - g0 == pytest.approx(1.0, abs=1e-5)
    assert w.k_geometry[2] == pytest.approx(1.0, abs=1e-5)
    # cell 3: 3 m along, 1.5 m higher, eye-to-cell d = sqrt(9 + 0.25) = 3.041 -> K_b = 0.5207
    assert w.k_geometry[3] == pytest.approx(1.0 - (math.sqrt(9.25) - 2.0) / 2.0, abs=1e-5)


def test_culling_boxes_stand_on_high_ground():
    """A camera looking level across a plateau 10 m up sees the grass on it; the same camera
    over flat ground sees nothing (the grass lies far below the frustum)."""
    params = small_params(**{"field.blocks_x": 4, "field.blocks_y": 4})
    high = build_layout(params, terrain=heightfield_of(params, lambda p: np.full(p.shape[:-1], 10.0)))
    flat = build_layout(params)
    cam = Camera.look_at((-8.0, 0.0, 10.3), (0.0, 0.0, 10.3), math.radians(60.0), 1.5)
    assert lod_weights(flat, cam, params).block_visible.sum() == 0
    assert lod_weights(high, cam, params).block_visible.sum() > 0


def test_fill_missing_takes_the_nearest_hit_height():
    z = np.zeros((5, 6))
    hit = np.zeros((5, 6), bool)
    z[:, :2], hit[:, :2] = 1.0, True  # left columns on the mesh at z = 1
    z[:, 5], hit[:, 5] = 3.0, True  # right column at z = 3
    filled = terrain.fill_missing(z, hit)
    np.testing.assert_allclose(filled[:, 2], 1.0)  # next to the left part
    np.testing.assert_allclose(filled[:, 4], 3.0)  # next to the right part
    assert np.all((filled >= 1.0) & (filled <= 3.0))
    np.testing.assert_array_equal(terrain.fill_missing(z, np.zeros_like(hit), fallback=-2.0), -2.0)


def test_fingerprint_follows_the_heights_and_bad_grids_name_the_terrain():
    a = terrain.Heightfield((0, 0), 1.0, np.zeros((3, 3)))
    b = terrain.Heightfield((0, 0), 1.0, np.zeros((3, 3)))
    c = terrain.Heightfield((0, 0), 1.0, np.eye(3))
    assert a.fingerprint() == b.fingerprint() != c.fingerprint()
    np.testing.assert_array_equal(terrain.ground_z(None, np.ones((4, 2))), 0.0)
    with pytest.raises(ParameterError, match="terrain"):
        terrain.Heightfield((0, 0), 1.0, np.zeros((1, 3)))
    with pytest.raises(ParameterError, match="terrain"):
        terrain.Heightfield((0, 0), 0.0, np.zeros((3, 3)))
    with pytest.raises(ParameterError, match="terrain"):
        terrain.Heightfield((0, 0), 1.0, np.full((3, 3), np.nan))


def test_drape_finds_the_top_surface_of_a_triangle_mesh():
    """Ray casts straight down, vectorised: a tilted quad (two triangles) under part of the grid
    gives the plane's heights where it lies and no hit elsewhere; a second, higher sheet over
    some samples wins there (the top of the terrain is what grass grows on)."""
    quad = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])
    corners = np.column_stack([quad, plane(quad)])
    tris = np.stack([corners[[0, 1, 2]], corners[[0, 2, 3]]])
    origin, spacing, nx, ny = np.array([-2.0, -2.0]), 0.25, 16, 16
    z, hit = terrain.drape(tris, origin, spacing, nx, ny)
    pts = terrain.grid_points(origin, spacing, nx, ny)
    inside = np.all(np.abs(pts) <= 1.0 + 1e-9, axis=-1)  # edges included (samples on the border)
    np.testing.assert_array_equal(hit, inside)
    np.testing.assert_allclose(z[inside], plane(pts[inside]), atol=2e-6)
    # Small chunks give the same answer.
    z2, hit2 = terrain.drape(tris, origin, spacing, nx, ny, chunk_pairs=7)
    np.testing.assert_array_equal(z2, z)
    np.testing.assert_array_equal(hit2, hit)
    # A roof at z = 5 over x in [0, 1], y in [0, 1] hides the plane below it.
    roof = np.array([[(0, 0, 5), (1, 0, 5), (1, 1, 5)], [(0, 0, 5), (1, 1, 5), (0, 1, 5)]], float)
    z3, _ = terrain.drape(np.concatenate([tris, roof]), origin, spacing, nx, ny)
    under = inside & np.all((pts >= 0.0) & (pts <= 1.0), axis=-1)
    np.testing.assert_allclose(z3[under], 5.0)
    np.testing.assert_allclose(z3[inside & ~under], z[inside & ~under])
    # A vertical wall (no area seen from above) is ignored.
    wall = np.array([[(0, -1, 0), (0, 1, 0), (0, 1, 9)]], float)
    z4, _ = terrain.drape(np.concatenate([tris, wall]), origin, spacing, nx, ny)
    np.testing.assert_array_equal(z4, z)


def test_cards_stand_on_the_ground_of_their_cell():
    """Cards (paper III.B) are vertical quads with their bottom edge on the ground: on a terrain
    both bottom corners sit at the cell centre's ground height and the card keeps its height,
    i.e. each card is the flat field's card lifted by cell_ground."""
    params = small_params(**{"wind.speed": 6.0})
    hilly = GrassField(params, terrain=heightfield_of(params, plane))
    flat = GrassField(params)
    hilly.seek(8)
    flat.seek(8)
    blocks = hilly.all_blocks()
    v = hilly.card_vertices(blocks).reshape(-1, 4, 3)
    w = flat.card_vertices(blocks).reshape(-1, 4, 3)
    ground = hilly.layout.cell_ground[hilly.layout.block_cells[blocks].ravel()]
    np.testing.assert_allclose(v[:, :2, 2], np.repeat(ground[:, None], 2, axis=1), atol=1e-6)
    np.testing.assert_allclose(ground, plane(hilly.layout.cell_center[hilly.layout.block_cells[blocks].ravel()]),
                               atol=2e-6)
    np.testing.assert_allclose(v - ground[:, None, None] * np.array([0, 0, 1], np.float32), w, atol=1e-5)
