"""Far grass sways with its patch (far_sway.py): what is shown, what it costs, and the bits.

A camera at a field's edge looks across it. The cells with blades show their own sway; past the
band beyond the blades' end a cell shows its patch's first cell's sway; in the band a cell's
pose lies between the two. Each is checked against a simulation of every cell of the field
(no camera), so the claims are about the physics, not about how far_sway computes them.
"""

import math

import numpy as np
import pytest
from windgrass.grass_addon import far_sway, schema
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.layout import cell_set
from windgrass.grass_addon.lod import Camera, cell_distances, views_eyes
from windgrass.grass_addon.solver import BladeSolver, base_oscillator

# 36 x 36 blocks of 8 x 8 cells of 0.1 m (28.8 m, above far_sway.SPLIT_CELLS), LOD distances a
# few metres, a stiff breeze
FIELD = {"field.blocks_x": 36, "field.blocks_y": 36, "field.cells_per_block": 8, "field.blades_per_cell": 1,
         "lod.blade_near": 1.5, "lod.blade_far": 3.0, "lod.card_near": 8.0, "lod.card_far": 12.0,
         "lod.screen_size": False, "simulation.preroll": 1.0, "simulation.epoch": 2.0,
         "wind.type": "moderate_breeze"}
FRAME = 30


def edge_camera() -> Camera:
    return Camera.look_at((0.0, -14.6, 1.2), (0.0, -6.0, 0.0), math.radians(70.0), 16 / 9)


def poses(field) -> dict[tuple[int, int], np.ndarray]:
    """{(block, cell in block): (bend, twist) of every joint, float64} of the field's window."""
    lay, st = field.layout, field.sim.state
    out = {}
    for i, block in enumerate(lay.block_ids.tolist()):
        for p, c in enumerate(lay.block_cells[i].tolist()):
            out[(block, p)] = np.concatenate([st.bend_t[..., c].ravel(), st.twist_t[:, c]]).astype(np.float64)
    return out


@pytest.fixture(scope="module")
def seen():
    params = schema.defaults().replace(FIELD)
    whole = GrassField(params)  # every cell simulated on its own: the reference
    assert whole.whole
    whole.seek(FRAME)
    field = GrassField(params)
    field.seek(FRAME, edge_camera())
    lay = field.layout
    d = cell_distances(lay.cell_center, lay.cell_ground, views_eyes(edge_camera()))
    where = {(int(b), p): float(d[c]) for i, b in enumerate(lay.block_ids) for p, c in enumerate(lay.block_cells[i])}
    return params, poses(whole), field, poses(field), where


def representative(p: int, cells: int = 8) -> int:
    y, x = divmod(p, cells)
    return (y - y % far_sway.GROUP) * cells + (x - x % far_sway.GROUP)


def test_blades_show_their_own_sway_and_far_patches_their_first_cells(seen):
    params, whole, field, shown, where = seen
    start = params.lod.blade_far
    end = far_sway.BAND * start
    own = [k for k, d in where.items() if d <= start]
    far = [k for k, d in where.items() if d >= end]
    assert len(own) > 500 and len(far) > 3000  # both kinds in view
    for key in own:  # every cell with blades: its own pose, the bits of the whole field's
        np.testing.assert_array_equal(shown[key], whole[key])
    for block, p in far:
        np.testing.assert_array_equal(shown[(block, p)], whole[(block, representative(p))])
    # and far grass still sways: its cells are bent along the wind, not standing at rest
    bend = np.array([shown[k][: 2 * params.blade.segments].reshape(-1, 2).sum(axis=0) for k in far])
    assert np.median(np.hypot(bend[:, 0], bend[:, 1])) > 0.05  # rad: a breeze bends a blade visibly


def test_in_the_band_a_pose_lies_between_its_own_and_its_patchs(seen):
    params, whole, field, shown, where = seen
    start, end = params.lod.blade_far, far_sway.BAND * params.lod.blade_far
    band = [k for k, d in where.items() if start + 0.05 < d < end - 0.05 and k[1] != representative(k[1])]
    assert len(band) > 50
    moved = 0
    for block, p in band:
        mine, theirs, got = whole[(block, p)], whole[(block, representative(p))], shown[(block, p)]
        lo, hi = np.minimum(mine, theirs), np.maximum(mine, theirs)
        assert np.all(got >= lo - 1e-6) and np.all(got <= hi + 1e-6)
        moved += not np.array_equal(got, mine)
    assert moved > 0.9 * len(band)  # (not its own pose: on its way to the patch's)
    # the weight grows with distance: nearer cells keep more of their own pose
    share = []
    for block, p in band:
        mine, theirs, got = whole[(block, p)], whole[(block, representative(p))], shown[(block, p)]
        gap = theirs - mine
        if np.abs(gap).max() > 1e-3:
            share.append((where[(block, p)], float(np.dot(got - mine, gap) / np.dot(gap, gap))))
    d, w = np.array(share).T
    assert np.corrcoef(d, w)[0, 1] > 0.95
    assert abs(np.interp(start + 0.5 * (end - start), d[np.argsort(d)], w[np.argsort(d)]) - 0.5) < 0.1


def test_far_grass_is_not_simulated_cell_by_cell(seen):
    """The cost: the cells stepped are those near the camera and one in GROUP^2 of the others."""
    params, _, field, _, where = seen
    sim = field.sim
    near, far = sim.near.layout.n_cells, sim.far.layout.n_cells
    beyond = sum(1 for d in where.values() if d > far_sway.KEEP * far_sway.BAND * params.lod.blade_far + 1.2)
    assert near + far < 0.5 * field.layout.n_cells
    assert far * far_sway.GROUP ** 2 <= field.layout.n_cells
    assert beyond > 0.5 * field.layout.n_cells  # (most of the window is far)


def test_a_cell_stepped_alone_has_the_bits_it_has_among_others():
    """The solver is per cell: a patch's first cell stepped on its own (far_sway) gets the bits it
    gets among the cells of a whole block, whichever of their rows swing in the chunk they are
    stepped with (in a blast: stiff and soft joints side by side, some swinging, some not)."""
    params = schema.defaults().replace({**FIELD, "wind.type": "blast"})
    lay = GrassField(params).layout
    blocks = np.arange(0, lay.n_blocks, 9)
    together = cell_set(lay, blocks)
    alone = [cell_set(lay, [b], lay.cells_per_block) for b in blocks]  # (each block's first cell)
    assert all(one.n_cells == 1 for one in alone)
    first = together.block_cells[:, 0]
    many, ones = BladeSolver(together, params), [BladeSolver(one, params) for one in alone]
    wind_field = GrassField(params).wind
    for frame in range(48):
        wind = np.ascontiguousarray(wind_field.sample(frame / 24, together.cell_center), dtype=np.float32)
        many.step(wind, 1 / 24)
        for i, one in enumerate(ones):
            one.step(np.ascontiguousarray(wind[first[i]:first[i] + 1]), 1 / 24)
    for name in ("bend_t", "twist_t", "bend_vel_t", "twist_vel_t", "bend_eq_t"):
        got = np.concatenate([getattr(one.state, name) for one in ones], axis=-1)
        np.testing.assert_array_equal(got, getattr(many.state, name)[..., first], err_msg=name)


INSIDE = Camera.look_at((0.0, 0.0, 1.0), (1.0, 1.0, 0.0), math.radians(90.0))
SHORT = {"lod.card_near": 3.2, "lod.card_far": 3.5}  # (a window that ends within the band)


@pytest.mark.parametrize("camera,lod", [(edge_camera(), {}), (INSIDE, SHORT)],
                         ids=["edge: near, band and far", "inside: every block near, a band"])
def test_a_wind_edit_in_place_draws_what_a_fresh_build_draws(camera, lod):
    """A new run (``GrassField.retune``) chooses its near blocks and band as a fresh field does."""
    params = schema.defaults().replace({**FIELD, **lod})
    edited = params.replace({"wind.speed": params.wind.speed + 3.0})
    field = GrassField(params)
    field.frame(FRAME, 0.0, camera)
    field.retune(edited)
    got = {p.role: p.vertices.copy() for p in field.frame(FRAME, 0.0, camera).roles()}
    fresh = GrassField(edited)
    want = {p.role: p.vertices for p in fresh.frame(FRAME, 0.0, camera).roles()}
    assert fresh.sim._band is not None  # (cells in the band: the case a new run must not lose)
    for role, vertices in want.items():
        np.testing.assert_array_equal(got[role], vertices, err_msg=role)


def test_the_recovery_oscillator_needs_no_solver_of_the_window():
    """Colliders' trampled grass sways back with each cell's base joint (eqs 29-31): the window's
    values, without a solver of every cell, are the solver's own bits."""
    params = schema.defaults().replace(FIELD)
    layout = GrassField(params).layout
    for got, want in zip(base_oscillator(layout, params), BladeSolver(layout, params).recovery_oscillator()):
        np.testing.assert_array_equal(got, want)


def test_a_small_field_steps_every_cell():
    """A field of at most SPLIT_CELLS cells (the Add menu's, 25.6 m) is simulated cell by cell
    everywhere, whatever the camera: every cell shows its own pose."""
    params = schema.defaults().replace({**FIELD, "field.blocks_x": 16, "field.blocks_y": 16})
    assert params.field.blocks_x ** 2 * params.field.cells_per_block ** 2 <= far_sway.SPLIT_CELLS
    whole = GrassField(params)
    whole.seek(FRAME)
    field = GrassField(params)
    field.seek(FRAME, edge_camera())
    assert field.sim.far is None
    reference = poses(whole)
    for key, pose in poses(field).items():
        np.testing.assert_array_equal(pose, reference[key])


def test_a_camera_moved_a_little_moves_no_pose_more_than_the_band_ramps(seen):
    """No pop as the camera moves: at one frame, a camera 2 cm further on changes a cell's pose
    by at most 2 cm / the band's width of the gap between its own pose and its patch's (the ramp
    by distance); a switch from one to the other would move it by the whole gap."""
    params, whole, field, shown, where = seen
    step = 0.02
    start, end = params.lod.blade_far, far_sway.BAND * params.lod.blade_far
    assert end - start >= 0.2 * start  # (a band a fifth of the blades' reach at least: a ramp, not a step)
    moved = GrassField(params)
    eye, target = edge_camera().position, np.array([0.0, -6.0, 0.0])
    moved.seek(FRAME, Camera.look_at(eye + (0.0, step, 0.0), target + (0.0, step, 0.0), math.radians(70.0), 16 / 9))
    after = poses(moved)
    changed = 0
    for block, p in shown.keys() & after.keys():
        gap = np.abs(whole[(block, representative(p))] - whole[(block, p)])
        change = np.abs(after[(block, p)] - shown[(block, p)])
        assert np.all(change <= gap * (step / (end - start)) * 1.001 + 1e-6), (block, p)
        changed += bool(change.max() > 0.0)
    assert changed > 20  # (cells in the band moved along their ramp)
