"""Blade strips and cards from cell angles (paper III.A-B, V.B): geometry checked by hand."""

from types import SimpleNamespace

import numpy as np
import pytest
from windgrass.grass_addon import atlas, blade, kinematics, schema
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.terrain import Heightfield, grid_for


def small_layout(**overrides):
    values = {"field.blocks_x": 2, "field.blocks_y": 3, "field.cells_per_block": 2, "field.blades_per_cell": 3,
              "blade.segments": 4, "field.cell_size": 0.2}
    values.update(overrides)
    return build_layout(schema.defaults().replace(values))


def cells_of(layout, bend=None, twist=None, card_offset=None):
    """CellData-like arrays (celldata.CellData has these fields)."""
    C, n = layout.n_cells, layout.segments
    return SimpleNamespace(
        bend=np.zeros((C, n, 2), np.float32) if bend is None else np.asarray(bend, np.float32),
        twist=np.zeros((C, n), np.float32) if twist is None else np.asarray(twist, np.float32),
        wind=np.zeros((C, 2), np.float32),
        card_offset=np.zeros((C, 3), np.float32) if card_offset is None else np.asarray(card_offset, np.float32))


def strips(layout, cells, blade_count=None):
    blocks = np.arange(layout.n_blocks)
    v = kinematics.blade_vertices(layout, cells, blocks, blade_count)
    return v.reshape(layout.n_blades, layout.segments + 1, 2, 3)


def random_cells(layout, seed=1, scale=0.4):
    rng = np.random.default_rng(seed)
    C, n = layout.n_cells, layout.segments
    return cells_of(layout, rng.normal(0, scale, (C, n, 2)), rng.normal(0, scale, (C, n)),
                    rng.normal(0, 0.05, (C, 3)))


def test_zero_bend_follows_rest_tilt():
    """No wind: each segment keeps its rest tilt; the tip height is sum (l/n) cos(tilt_j)."""
    layout = small_layout()
    v = strips(layout, cells_of(layout))
    mid = v.mean(axis=2)  # joint centres
    seg = layout.blade_length / layout.segments
    tilt = layout.blade_rest_tilt.astype(np.float64)
    np.testing.assert_allclose(mid[:, 0], layout.blade_root, atol=1e-6)
    np.testing.assert_allclose(mid[:, -1, 2], seg * np.cos(tilt).sum(axis=1), rtol=1e-5, atol=1e-6)
    # ... and leans towards its facing direction by sum (l/n) sin(tilt_j)
    reach = seg * np.sin(tilt).sum(axis=1)
    lean = mid[:, -1, :2] - layout.blade_root[:, :2]
    facing = np.stack([np.cos(layout.blade_facing), np.sin(layout.blade_facing)], axis=1)
    np.testing.assert_allclose(lean, facing * reach[:, None], atol=2e-6)


def test_segment_lengths_preserved_under_any_bend():
    """Segments are rigid (paper III.A): joint-to-joint distance stays l/n for any bend and twist."""
    layout = small_layout()
    mid = strips(layout, random_cells(layout, scale=0.8)).mean(axis=2)
    lengths = np.linalg.norm(np.diff(mid, axis=1), axis=2)
    np.testing.assert_allclose(lengths, np.repeat(layout.blade_length[:, None] / layout.segments,
                                                  layout.segments, axis=1), rtol=1e-5)


def test_bend_along_x_moves_tips_along_x():
    """Upright blades (alpha = 0, so no gravity lean) under a bend of b per joint along +X:
    segment j tilts by (j+1) b towards +X, so the tip sits at sum l/n (sin((j+1)b), 0, cos((j+1)b))."""
    layout = small_layout(**{"blade.inclination": 0.0})
    n, b = layout.segments, 0.2
    bend = np.zeros((layout.n_cells, n, 2))
    bend[:, :, 0] = b
    tip = strips(layout, cells_of(layout, bend)).mean(axis=2)[:, -1]
    seg = layout.blade_length / n
    angles = b * np.arange(1, n + 1)
    np.testing.assert_allclose(tip[:, 0] - layout.blade_root[:, 0], seg * np.sin(angles).sum(), rtol=1e-5)
    np.testing.assert_allclose(tip[:, 1], layout.blade_root[:, 1], atol=1e-6)
    np.testing.assert_allclose(tip[:, 2], seg * np.cos(angles).sum(), rtol=1e-5)
    assert np.all(tip[:, 0] > layout.blade_root[:, 0])


def test_twist_rotates_strip_width():
    """A quarter turn of twist at the root joint turns the whole blade by 90 degrees (the joints
    above carry it, the twist is cumulative): the width vector (right - left), perpendicular to the
    facing at rest, becomes antiparallel to the facing. A twist at the last joint turns only the
    last segment (its bottom edge and the tip edge)."""
    layout = small_layout(**{"blade.inclination": 0.0})
    n = layout.segments
    f = layout.blade_facing
    taper = 1.0 + (layout.params.blade.tip_width - 1.0) * np.arange(n + 1) / n
    w = layout.blade_width[:, None] * taper[None, :]
    side = np.stack([-np.sin(f), np.cos(f)], axis=1)
    facing = np.stack([np.cos(f), np.sin(f)], axis=1)

    twist = np.zeros((layout.n_cells, n))
    twist[:, 0] = np.pi / 2
    v = strips(layout, cells_of(layout, twist=twist))
    width_vec = v[:, :, 1] - v[:, :, 0]  # (B, n+1, 3)
    np.testing.assert_allclose(width_vec[:, :, :2], -facing[:, None, :] * w[:, :, None], atol=1e-6)
    assert np.all(width_vec[..., 2] == 0.0)

    twist = np.zeros((layout.n_cells, n))
    twist[:, -1] = np.pi / 2
    width_vec = np.diff(strips(layout, cells_of(layout, twist=twist)), axis=2)[:, :, 0]
    np.testing.assert_allclose(width_vec[:, : n - 1, :2], side[:, None, :] * w[:, : n - 1, None], atol=1e-6)
    np.testing.assert_allclose(width_vec[:, n - 1:, :2], -facing[:, None, :] * w[:, n - 1:, None], atol=1e-6)
    # the tip is narrower than the root by blade.tip_width (linear taper)
    np.testing.assert_allclose(np.linalg.norm(width_vec[:, -1], axis=1),
                               layout.params.blade.tip_width * layout.blade_width, rtol=1e-5, atol=1e-7)


def test_hidden_blades_collapse_onto_their_root():
    """Eq 9: only slots < N of a cell are drawn; the others shrink to their root point."""
    layout = small_layout()
    count = np.ones(layout.n_cells, np.int32)
    count[::2] = 2
    v = strips(layout, random_cells(layout), count)
    hidden = layout.blade_slot >= count[layout.blade_cell]
    assert hidden.any() and (~hidden).any()
    np.testing.assert_array_equal(v[hidden], np.broadcast_to(layout.blade_root[hidden][:, None, None, :],
                                                             v[hidden].shape))
    shown_height = v[~hidden][:, -1, :, 2]
    assert np.all(shown_height > 0.0)


def test_matches_per_blade_formula_and_block_concatenation():
    """Vectorised, chunked and threaded kernel == the per-blade formula of the module docstring;
    blocks come out in the order asked, each with the same topology."""
    layout = small_layout(**{"field.blocks_x": 3})
    cells = random_cells(layout, seed=7)
    n = layout.segments
    blocks = np.array([4, 0, 5, 1])
    old = kinematics.CHUNK_BLADES
    try:
        kinematics.CHUNK_BLADES = layout.blades_per_block  # one block per chunk: exercises the pool
        kinematics._CACHE.clear()
        got = kinematics.blade_vertices(layout, cells, blocks)
    finally:
        kinematics.CHUNK_BLADES = old
        kinematics._CACHE.clear()
    got = got.reshape(len(blocks), layout.blades_per_block, n + 1, 2, 3)
    tip_w = layout.params.blade.tip_width
    for i, block in enumerate(blocks):
        for local, b in enumerate(range(block * layout.blades_per_block, (block + 1) * layout.blades_per_block)):
            c = layout.blade_cell[b]
            f = float(layout.blade_facing[b])
            p = layout.blade_root[b].astype(np.float64)
            T_bend = np.zeros(2)
            phi = np.cumsum(cells.twist[c])  # Phi_j = sum_{k<=j} twist; the tip joint takes Phi_{n-1}
            expect = []
            for j in range(n + 1):
                s = np.array([-np.sin(f + phi[min(j, n - 1)]), np.cos(f + phi[min(j, n - 1)]), 0.0])
                w = layout.blade_width[b] * (1 + (tip_w - 1) * j / n)
                expect.append([p - s * w / 2, p + s * w / 2])
                if j == n:
                    break
                T_bend += cells.bend[c, j]
                T = layout.blade_rest_tilt[b, j] * np.array([np.cos(f), np.sin(f)]) + T_bend
                a = np.linalg.norm(T)
                theta = min(a, blade.GROUND_TILT)  # the ground stops the segment
                hor = np.sin(theta) * T / a if a > 0 else np.zeros(2)
                p = p + layout.blade_length[b] / n * np.array([hor[0], hor[1], np.cos(theta)])
            np.testing.assert_allclose(got[i, local], np.array(expect), atol=2e-6)


def test_threads_and_out_give_identical_results():
    layout = small_layout(**{"field.blocks_x": 4})
    cells = random_cells(layout, seed=3)
    blocks = np.arange(layout.n_blocks)
    old = kinematics.THREADS, kinematics.CHUNK_BLADES
    try:
        kinematics.CHUNK_BLADES = 2 * layout.blades_per_block
        kinematics._CACHE.clear()
        kinematics.THREADS = 1
        one = kinematics.blade_vertices(layout, cells, blocks)
        kinematics.THREADS = 2
        out = np.full((kinematics.blade_vertex_count(layout, len(blocks)) + 5, 3), np.nan, np.float32)
        two = kinematics.blade_vertices(layout, cells, blocks, out=out)
    finally:
        kinematics.THREADS, kinematics.CHUNK_BLADES = old
        kinematics._CACHE.clear()
    assert np.shares_memory(two, out)
    np.testing.assert_array_equal(one, two)
    assert one.dtype == np.float32 and one.flags.c_contiguous
    with pytest.raises(ValueError, match="float32"):
        kinematics.blade_vertices(layout, cells, blocks, out=np.empty((3, 3), np.float32))


def test_faces_and_uvs_describe_the_strips():
    layout = small_layout()
    n, bpb = layout.segments, layout.blades_per_block
    faces = kinematics.blade_faces(layout)
    uvs = kinematics.blade_uvs(layout).reshape(-1, 4, 2)
    assert faces.shape == (bpb * n, 4) and faces.dtype == np.int32
    assert faces.min() == 0 and faces.max() == bpb * (n + 1) * 2 - 1
    # every vertex of the block is used, the first quad is (root left, root right, j1 right, j1 left)
    assert len(np.unique(faces)) == bpb * (n + 1) * 2
    np.testing.assert_array_equal(faces[0], [0, 1, 3, 2])
    # uv: u = 0 on left vertices (even ids), 1 on right; v = joint / n (0 at the root, 1 at the tip)
    np.testing.assert_array_equal(uvs[..., 0], faces % 2)
    np.testing.assert_allclose(uvs[..., 1], (faces % (2 * (n + 1))) // 2 / n, atol=1e-7)
    cf, cu = kinematics.card_faces(layout), atlas.card_uvs(layout)
    assert cf.shape == (layout.cells_per_block_total, 4) and cu.shape == (layout.cells_per_block_total * 4, 2)
    # each card spans one variant of the atlas, the same for the same cell of every block
    variant = atlas.card_variants(layout)
    assert variant.min() >= 0 and variant.max() < atlas.CARD_VARIANTS
    assert len(set(variant.tolist())) > 1
    corners = cu.reshape(-1, 4, 2)
    np.testing.assert_allclose(corners[:, :, 0].min(axis=1), variant / atlas.CARD_VARIANTS, atol=1e-7)
    np.testing.assert_allclose(corners[:, :, 0].max(axis=1), (variant + 1) / atlas.CARD_VARIANTS, atol=1e-7)
    np.testing.assert_array_equal(corners[:, :, 1], np.broadcast_to([0, 0, 1, 1], corners.shape[:2]))


def test_card_top_moves_by_eq34_offset_and_turns_with_twist():
    """Paper V.B: the card's top edge is lifted by its height and moved by M' (eq 34); the bottom
    stays on the ground; its width is lod.card_width cells; twist turns the top edge."""
    layout = small_layout()
    C, n = layout.n_cells, layout.segments
    # eq 34 for a bend sum omega = 0.5 rad under wind along +Y: M' = (0, L sin w, L cos w - L)
    L, omega = layout.card_height[:, None], 0.5
    offset = np.concatenate([np.zeros((C, 1)), L * np.sin(omega), L * np.cos(omega) - L], axis=1)
    twist = np.zeros((C, n))
    twist[:, -1] = 0.3
    cells = cells_of(layout, twist=twist, card_offset=offset)
    blocks = np.arange(layout.n_blocks)
    v = kinematics.card_vertices(layout, cells, blocks).reshape(-1, 4, 3)
    order = layout.block_cells[blocks].ravel()
    centre = layout.card_center[order]
    bottom_mid, top_mid = v[:, :2].mean(axis=1), v[:, 2:].mean(axis=1)
    np.testing.assert_allclose(bottom_mid[:, :2], centre, atol=1e-6)
    # the card stands inside its cell (anywhere in it: no rows of cards along the grid)
    assert np.abs(centre - layout.cell_center[order]).max() <= 0.5 * layout.cell_size + 1e-6
    assert np.abs(centre - layout.cell_center[order]).std() > 0.1 * layout.cell_size
    assert np.all(v[:, :2, 2] == 0.0)
    lift = top_mid - bottom_mid
    np.testing.assert_allclose(lift, offset[order] + np.array([0, 0, 1.0]) * layout.card_height[order, None],
                               atol=1e-6)
    width = layout.params.lod.card_width * layout.cell_size
    bottom_dir = v[:, 1] - v[:, 0]
    top_dir = v[:, 2] - v[:, 3]
    np.testing.assert_allclose(np.linalg.norm(bottom_dir, axis=1), width, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(top_dir, axis=1), width, rtol=1e-5)
    turn = np.arctan2(top_dir[:, 1], top_dir[:, 0]) - np.arctan2(bottom_dir[:, 1], bottom_dir[:, 0])
    np.testing.assert_allclose(np.remainder(turn + np.pi, 2 * np.pi) - np.pi, 0.3, atol=1e-5)


def test_quads_face_the_way_the_blade_leans():
    """Face normals ((v1 - v0) x (v3 - v0), counter-clockwise) point to the blade's facing
    azimuth, the direction it leans at rest (layout.blade_facing)."""
    layout = small_layout()
    v = kinematics.blade_vertices(layout, cells_of(layout), np.arange(layout.n_blocks))
    faces = kinematics.blade_faces(layout)
    per_block = layout.blades_per_block * (layout.segments + 1) * 2
    quads = v.reshape(layout.n_blocks, per_block, 3)[:, faces]  # (blocks, faces, 4, 3)
    normal = np.cross(quads[..., 1, :] - quads[..., 0, :], quads[..., 3, :] - quads[..., 0, :])
    normal = normal.reshape(layout.n_blades, layout.segments, 3)
    facing = np.stack([np.cos(layout.blade_facing), np.sin(layout.blade_facing)], axis=1)
    assert np.all(np.einsum("bjk,bk->bj", normal[..., :2], facing) > 0.0)


def test_any_block_order_with_blade_counts_matches_the_full_field():
    """Blocks asked in any order (the bridge asks for the visible ones) give the same per-block
    vertices as the whole field, with eq 9 counts applied (chunks of one block: gathers, threads);
    the blocks' per-blade constants are worked out when first drawn, some now and others later."""
    layout = small_layout(**{"field.blocks_x": 3})
    cells = random_cells(layout, seed=11)
    count = (np.arange(layout.n_cells) % 4).astype(np.int32)  # 0..3 of 3 blades
    full = kinematics.blade_vertices(layout, cells, np.arange(layout.n_blocks), count)
    per_block = full.reshape(layout.n_blocks, -1, 3)
    order = np.array([5, 2, 3, 0])
    old = kinematics.CHUNK_BLADES
    try:
        kinematics.CHUNK_BLADES = layout.blades_per_block
        kinematics._CACHE.clear()
        got = kinematics.blade_vertices(layout, cells, order, count).reshape(len(order), -1, 3)
        assert kinematics._constants(layout).ready.sum() == len(order)
        again = kinematics.blade_vertices(layout, cells, np.arange(layout.n_blocks), count)
    finally:
        kinematics.CHUNK_BLADES = old
        kinematics._CACHE.clear()
    np.testing.assert_array_equal(got, per_block[order])
    np.testing.assert_array_equal(again, full)


def test_joint_major_cell_data_gives_the_same_strips_and_cards():
    """celldata.CellData carries the solver's joint-major arrays (bend_t (n, 2, C), twist_t (n, C));
    the kernel reads them directly. Same numbers as the cell-major bend/twist, bit for bit, for
    the whole field, for blocks in any order and for the cards."""
    from windgrass.grass_addon.celldata import CellData

    layout = small_layout(**{"field.blocks_x": 3})
    cells = random_cells(layout, seed=5)
    joint_major = CellData(wind=cells.wind, card_offset=cells.card_offset,
                           bend_t=np.ascontiguousarray(cells.bend.transpose(1, 2, 0)),
                           twist_t=np.ascontiguousarray(cells.twist.T))
    count = (np.arange(layout.n_cells) % 4).astype(np.int32)
    for blocks in (np.arange(layout.n_blocks), np.array([5, 2, 3, 0]), np.array([1, 2, 4])):
        np.testing.assert_array_equal(kinematics.blade_vertices(layout, joint_major, blocks, count),
                                      kinematics.blade_vertices(layout, cells, blocks, count))
        np.testing.assert_array_equal(kinematics.card_vertices(layout, joint_major, blocks),
                                      kinematics.card_vertices(layout, cells, blocks))


def test_chunks_across_block_rows_and_plain_gathers_match_the_full_field():
    """Chunks of several blocks that cross block rows or skip blocks (the per-cell gathers split
    them into runs of one block row), and the index-array gather used when the layout's cells are
    not in the row-major square order, give the same vertices, bit for bit, as the whole field."""
    layout = small_layout(**{"field.blocks_x": 3, "field.blocks_y": 3})
    cells = random_cells(layout, seed=13)
    count = (np.arange(layout.n_cells) % 4).astype(np.int32)
    full = kinematics.blade_vertices(layout, cells, np.arange(layout.n_blocks), count)
    per_block = full.reshape(layout.n_blocks, -1, 3)
    order = np.array([1, 2, 3, 4, 0, 8, 6, 7])
    old = kinematics.CHUNK_BLADES
    try:
        kinematics.CHUNK_BLADES = 4 * layout.blades_per_block  # chunks [1 2 3 4], [0 8 6 7]
        for plain in (False, True):
            kinematics._CACHE.clear()
            if plain:
                kinematics._constants(layout).grid = None
            got = kinematics.blade_vertices(layout, cells, order, count).reshape(len(order), -1, 3)
            np.testing.assert_array_equal(got, per_block[order])
    finally:
        kinematics.CHUNK_BLADES = old
        kinematics._CACHE.clear()


def test_the_ground_stops_every_blade_and_card():
    """Bends far past lying flat (up to the solver's bound at every joint): no blade vertex and no
    card corner goes below the flat ground, and a pressed-down blade lies close to it."""
    layout = small_layout(**{"blade.segments": 6})
    rng = np.random.default_rng(5)
    C, n = layout.n_cells, layout.segments
    direction = rng.uniform(0, 2 * np.pi, C)
    bend = np.zeros((C, n, 2), np.float32)
    bend[..., 0] = (np.cos(direction) * 1.2)[:, None]
    bend[..., 1] = (np.sin(direction) * 1.2)[:, None]
    from windgrass.grass_addon.celldata import card_offset

    cells = cells_of(layout, bend, card_offset=card_offset(layout.card_height, bend.sum(axis=1).T))
    blocks = np.arange(layout.n_blocks)
    v = kinematics.blade_vertices(layout, cells, blocks)
    assert v[:, 2].min() >= 0.0
    tips = v.reshape(-1, n + 1, 2, 3)[:, -1, :, 2]
    assert np.median(tips) < 0.1 * layout.blade_length.mean()  # pressed down, not floating
    cards = kinematics.card_vertices(layout, cells, blocks)
    assert cards[:, 2].min() >= 0.0


def test_a_slope_stops_blades_leaning_uphill():
    """On a plane z = 0.5 x (27 degrees) a blade bent hard uphill lies along the slope, above it."""
    params = schema.defaults().replace({"field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 2,
                                        "field.blades_per_cell": 3, "blade.segments": 5, "field.cell_size": 0.2})
    origin, spacing, nx, ny = grid_for(params)
    xs = origin[0] + spacing * np.arange(nx + 1)
    heights = np.tile(0.5 * xs, (ny + 1, 1)).astype(np.float32)
    layout = build_layout(params, terrain=Heightfield(origin, spacing, heights))
    C, n = layout.n_cells, layout.segments
    bend = np.zeros((C, n, 2), np.float32)
    bend[..., 0] = 0.6  # towards +x: uphill, 3 rad in all
    v = kinematics.blade_vertices(layout, cells_of(layout, bend), np.arange(layout.n_blocks))
    centres = v.reshape(-1, n + 1, 2, 3).mean(axis=2)
    assert (centres[..., 2] - 0.5 * centres[..., 0]).min() >= -1e-5
    # the strip's edges are level across the blade: at most half a width times the slope lower
    assert (v[:, 2] - 0.5 * v[:, 0]).min() >= -0.5 * 0.5 * layout.blade_width.max() - 1e-5
    tips = centres[:, -1]
    roots = layout.blade_root
    assert np.all(tips[:, 0] > roots[:, 0])  # they still lean uphill


def test_seed_heads_widen_the_joint_below_the_tip_and_flowers_open_into_a_small_head():
    """Meadow heads (meadow.py): a seed head makes the strip ``head`` times the blade's root width
    at joint n - 1; a flower of the strip (head shape "flower") that wide at joint n - 1 and 0.6 of
    it at the tip (its rim), its two top segments together 0.7 times its width long, the stem's
    other segments equal and the blade its whole length; the other joints keep the linear taper,
    and so does the whole stem of a flower or a seed head that is a mesh (a daisy, timothy's spike:
    heads.py), a flower's top segments as short. Checked by hand against the width vector of every
    joint, untwisted and unbent, and the joints' distances."""
    from windgrass.grass_addon import presets

    params = presets.apply_preset(schema.defaults(), "meadow")
    rows = [dict(r) for r in params.blade.species]
    rows[3]["head_shape"] = "flower"  # the buttercups a cup of the strip, the daisies meshes
    rows[1]["head_shape"] = "spike"  # the meadow grass's seed heads spindles of the strip, timothy's spikes
    assert rows[4]["head_shape"] == "daisy" and rows[0]["head_shape"] == "seed"
    params = params.replace({"field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 4,
                             "field.blades_per_cell": 3, "blade.species": tuple(rows)})
    layout = build_layout(params)
    n = layout.segments
    cup, daisy = (layout.blade_flower > 0) & (layout.blade_species == 3), layout.blade_species == 4
    assert (layout.blade_head > 0).any() and cup.any() and (layout.blade_flower[daisy] > 0).any()
    width = np.linalg.norm(np.diff(strips(layout, cells_of(layout)), axis=2)[:, :, 0], axis=2)
    taper = 1.0 + (params.blade.tip_width - 1.0) * np.arange(n + 1) / n
    expected = layout.blade_width[:, None] * taper[None, :]
    spindle = (layout.blade_head > 0) & (layout.blade_species != 1)  # (a spike's stem stays a thin strip)
    assert spindle.any() and ((layout.blade_head > 0) & (layout.blade_species == 1)).any()
    expected[:, n - 1] = np.where(spindle, layout.blade_width * layout.blade_head, expected[:, n - 1])
    flower = layout.blade_flower > 0
    expected[cup, n - 1] = layout.blade_width[cup] * layout.blade_flower[cup]
    expected[cup, n] = 0.6 * layout.blade_width[cup] * layout.blade_flower[cup]
    np.testing.assert_allclose(width, expected, rtol=1e-5, atol=1e-7)
    centre = strips(layout, cells_of(layout)).mean(axis=2)
    segment = np.linalg.norm(np.diff(centre, axis=1), axis=2)
    head = 0.7 * layout.blade_width[flower] * layout.blade_flower[flower]
    np.testing.assert_allclose(segment[flower, n - 2:], np.repeat(head[:, None] / 2, 2, axis=1), rtol=1e-4)
    np.testing.assert_allclose(segment[flower, : n - 2], np.repeat(
        ((layout.blade_length[flower] - head) / (n - 2))[:, None], n - 2, axis=1), rtol=1e-4)
    np.testing.assert_allclose(segment[~flower], np.repeat(layout.blade_length[~flower, None] / n, n, axis=1),
                               rtol=1e-4)


def test_the_cards_are_their_plain_statement_corner_by_corner():
    """``card_vertices`` (bottom edges kept by the layout, records gathered) gives the bits of
    ``card_vertices_plain`` (each corner stated: foot -+ half the width along the card's facing;
    top = foot + M' of eq 34 -+ half the width along the facing turned by the total twist), for
    blocks in any order, on flat ground and on a hill, and after a LOD edit of the cards' width."""
    params = schema.defaults().replace({"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4,
                                        "field.blades_per_cell": 2})
    origin, spacing, nx, ny = grid_for(params)
    x, y = np.meshgrid(origin[0] + spacing * np.arange(nx + 1), origin[1] + spacing * np.arange(ny + 1))
    hill = Heightfield(origin, spacing, (0.3 * x - 0.2 * y + 0.1 * np.sin(3.0 * x)).astype(np.float32))
    for terrain in (None, hill):
        layout = build_layout(params, terrain)
        cells = random_cells(layout, seed=7)
        for blocks in (np.arange(layout.n_blocks), np.array([5, 2, 3, 0]), np.array([4])):
            want = kinematics.card_vertices_plain(layout, cells, blocks)
            np.testing.assert_array_equal(kinematics.card_vertices(layout, cells, blocks), want)
        wider = layout.retitled(layout.params.replace({"lod.card_width": 2.2}), layout.species_color,
                                layout.species_head_color)
        got = kinematics.card_vertices(wider, cells, np.arange(layout.n_blocks)).reshape(-1, 4, 3)
        width = np.linalg.norm(got[:, 1, :2] - got[:, 0, :2], axis=1)
        np.testing.assert_allclose(width, 2.2 * layout.cell_size, rtol=1e-5)
        np.testing.assert_array_equal(got.reshape(-1, 3), kinematics.card_vertices_plain(wider, cells,
                                                                                          np.arange(layout.n_blocks)))
