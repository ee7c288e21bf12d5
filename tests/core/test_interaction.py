"""Colliders push and trample the grass, force fields blow it (interaction.py, forces.py).

The field: 4 x 4 blocks of 8 cells of 0.1 m (3.2 m square), 4 blades a cell, a 3 m/s breeze; a
ball of 0.3 m radius rolls along y = 0 from x = -2 m to x = 2 m in 2 s (frames 1-49 at 24 fps).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from windgrass.grass_addon import forces, interaction, schema
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.frame import BLADES, needs
from windgrass.grass_addon.lod import Camera

BALL = """
[field]
blocks_x = 4
blocks_y = 4
cells_per_block = 8
cell_size = 0.1
blades_per_cell = 4
[wind]
speed = 3.0
[interaction]
recovery = 3.0
[[colliders]]
radius = 0.3
path = [{time = 0.0, position = [-2.0, 0.0, 0.3]}, {time = 2.0, position = [2.0, 0.0, 0.3]}]
"""


def _tips(field: GrassField, frame: int) -> np.ndarray:
    field.seek(frame)
    v = field.blade_vertices(field.all_blocks())
    n = field.layout.segments
    return v.reshape(-1, n + 1, 2, 3)[:, -1].mean(axis=1)


@pytest.fixture(scope="module")
def ball():
    params = schema.loads_toml(BALL)
    return params, GrassField(params), GrassField(params.replace({"interaction.colliders": []}))


def test_no_blade_tip_is_inside_the_rolling_ball(ball):
    params, field, _ = ball
    tolerance = params.interaction.tolerance
    for frame in range(1, 50, 4):
        tips = _tips(field, frame)
        centre = field.interaction.spheres(field.interaction.time(frame)).centres[0]
        depth = 0.3 - np.linalg.norm(tips - centre, axis=1)
        assert depth.max() <= tolerance + 1e-4, (frame, float(depth.max()))


def test_the_trail_is_flattened_along_the_roll_then_rises_back_within_the_recovery(ball):
    """Frame 25 (the ball passed x = -1 m half a second ago, it is 1 m further on): the trail's
    blades around x = -1 m lie low and point along +x (the ball's travel); 3 s after the ball
    left the trail (the recovery), every tip is within 10 % of its blade's length of the wind-only field's."""
    params, field, plain = ball
    layout = field.layout
    roots = layout.blade_root
    trail = (np.abs(roots[:, 0] + 1.0) < 0.3) & (np.abs(roots[:, 1]) < 0.1)
    tips, free = _tips(field, 25), _tips(plain, 25)
    height, free_height = tips[trail, 2] - roots[trail, 2], free[trail, 2] - roots[trail, 2]
    assert np.median(height) < 0.5 * np.median(free_height), (np.median(height), np.median(free_height))
    lean = tips[trail, :2] - roots[trail, :2]
    assert np.median(lean[:, 0]) > 0.1 and np.median(lean[:, 0]) > 3 * np.median(np.abs(lean[:, 1]))
    # the ball's back (0.3 m behind its centre) left the trail's last blades (x = -0.7 m) at
    # t = (-0.7 + 0.3 + 2) / 2 = 0.8 s: 3 s later, t = 3.8 s, and a frame
    later = 1 + int(math.ceil((0.8 + params.interaction.recovery) * 24)) + 1
    tips, free = _tips(field, later), _tips(plain, later)
    length = layout.blade_length[trail]
    assert np.max(np.linalg.norm(tips[trail] - free[trail], axis=1) / length) < 0.1


def test_frame_80_alone_equals_frame_80_of_a_sequence(ball):
    params, _, _ = ball
    alone = GrassField(params)
    seq = GrassField(params)
    for frame in range(1, 81):
        seq.seek(frame)
    a = alone.blade_vertices(alone.all_blocks()) if alone.seek(80) is not None else None
    b = seq.blade_vertices(seq.all_blocks())
    assert np.array_equal(a, b)
    assert np.array_equal(alone.card_vertices(alone.all_blocks()), seq.card_vertices(seq.all_blocks()))


def test_the_far_canopys_trail_map_follows_the_ball_and_fades_with_the_recovery(ball):
    """The far canopy's trail (no cell is simulated there): at frame 25 (t = 1 s) the ball has
    rolled from the field's edge (x = -1.6 m) to x = 0 at 2 m/s; the map is flat along its path
    behind it and only there, flattest where it passed last; 3 s (the recovery) after it stopped
    pressing, no trail is left. Frame 25 alone gives the same map."""
    params, field, _ = ball
    trail = field.interaction.trail_map(25)
    x0, y0, x1, y1 = trail.extent
    assert trail.flat.shape == (interaction.TRAIL_PIXELS, interaction.TRAIL_PIXELS)
    assert x1 - x0 == pytest.approx(y1 - y0) and x0 < -1.5 and x1 > 0.3 and y0 < -0.3 and y1 > 0.3
    pixel = (x1 - x0) / trail.flat.shape[1]
    xs = x0 + (np.arange(trail.flat.shape[1]) + 0.5) * pixel
    ys = y0 + (np.arange(trail.flat.shape[0]) + 0.5) * pixel
    row = trail.flat[np.argmin(np.abs(ys))]  # along y = 0, the ball's line
    assert np.all(row[(xs > -1.4) & (xs < -0.1)] > 0.5) and np.all(row[xs > 0.6] == 0.0)
    assert row[np.argmin(np.abs(xs + 0.2))] > row[np.argmin(np.abs(xs + 1.4))]  # pressed later: flatter
    assert np.all(trail.flat[np.abs(ys) > 0.5] == 0.0)  # the ball is 0.6 m wide
    # the ball's last press is before t = 2 s (frame 49), at the field's edge; the recovery is 3 s
    assert field.interaction.trail_map(49 + 3 * 24 + 1) is None
    assert field.interaction.trail_map(49 + 3 * 24 - 12) is not None
    assert GrassField(params).interaction.trail_map(25).flat.tobytes() == trail.flat.tobytes()


def test_the_trail_maps_merged_chunks_stay_within_a_chunks_recovery(ball, monkeypatch):
    """A cell's presses within a chunk of frames count as one (the strongest, at its last frame):
    the trail map is never less flat than frame by frame, flatter by no more than the far
    recovery falls within a chunk's span (9 frames of the 72-frame window: 1/3 s), and by much
    less on average."""
    params = ball[0]
    field = GrassField(params)
    assert field.interaction.chunk == 9
    merged = field.interaction.trail_map(40)
    monkeypatch.setattr(interaction, "CHUNKS_PER_WINDOW", 10**9)
    exact = GrassField(params).interaction.trail_map(40)
    assert merged.extent == exact.extent
    difference = merged.flat - exact.flat
    tau = np.linspace(0.0, params.interaction.recovery, 601)
    span = 8 / 24  # the first and last frame of a chunk, at 24 fps
    fall = float(np.max(interaction.far_recovery(tau, 3.0) - interaction.far_recovery(tau + span, 3.0)))
    trail = exact.flat > 0
    assert trail.sum() > 100
    assert difference.min() >= -1e-6 and difference.max() <= fall + 1e-6
    assert np.abs(difference[trail]).mean() < 0.1 * fall


def _trample(params, frame: int):
    """Per global cell id how flat the trampled cells are at ``frame`` (a fresh field, the ball's
    stems: K/M 40 s^-2, C/M 2 s^-1)."""
    field = GrassField(params)
    it = field.interaction
    window = interaction.WindowCells(field.layout, it.grid)
    count = len(window.ids)
    local, flat, _ = it.trample(frame, window, np.full(count, 40.0), np.full(count, 2.0))
    out = np.zeros(count)
    out[local] = flat
    return out


def test_the_trample_counts_a_cells_presses_within_a_chunk_as_one(ball, monkeypatch):
    """The near trample takes a chunk's presses of a cell as one, as the trail map does: at frame
    25 (every press within the held part of the recovery) never less flat than frame by frame, and
    flatter by no more than the held curve falls within a chunk's span."""
    params = ball[0]
    merged = _trample(params, 25)
    monkeypatch.setattr(interaction, "CHUNKS_PER_WINDOW", 10**9)
    exact = _trample(params, 25)
    difference = merged - exact
    held = interaction.HOLD * params.interaction.recovery
    fall = float(interaction._held(np.array([held - 8 / 24]), held)[0] - interaction.HELD_FLAT)
    assert (exact > 0.5).sum() > 100
    assert np.array_equal(merged > 0, exact > 0)
    assert difference.min() >= -1e-9 and difference.max() <= fall + 1e-9
    assert np.abs(difference[exact > 0]).mean() < 0.1 * fall


def test_frames_asked_in_any_order_give_the_same_trample_and_trail(ball):
    """Played, scrubbed back, motion blur's N - 1, N, N + 1, a jump: each frame's trampled cells and
    trail map equal those of a fresh field asked for that frame alone."""
    params = ball[0]
    field = GrassField(params)
    it = field.interaction
    window = interaction.WindowCells(field.layout, it.grid)
    omega2, damping = np.full(len(window.ids), 40.0), np.full(len(window.ids), 2.0)
    for frame in (20, 21, 22, 23, 22, 21, 27, 26, 28, 9, 60, 40, 41):
        got = it.trample(frame, window, omega2, damping)
        fresh = GrassField(params).interaction
        want = fresh.trample(frame, interaction.WindowCells(field.layout, fresh.grid), omega2, damping)
        assert len(want[0]) > 20, frame
        assert all(np.array_equal(a, b) for a, b in zip(got, want)), frame
        assert it.trail_map(frame).flat.tobytes() == fresh.trail_map(frame).flat.tobytes(), frame


@pytest.mark.slow  # (many seconds: dev.py test --quick leaves it out)
def test_a_collider_far_from_the_window_adds_no_work():
    """A 1 km field seen from its centre; a ball rolling 400 m away touches no simulated cell:
    the frame is bit for bit the field without it."""
    base = schema.defaults().replace({"field.blocks_x": 625, "field.blocks_y": 625})
    far = base.replace({"interaction.colliders": [{"radius": 0.5, "path": [
        {"time": 0.0, "position": [400.0, 400.0, 0.5]}, {"time": 2.0, "position": [404.0, 400.0, 0.5]}]}]})
    cam = Camera.look_at((0.0, -5.0, 1.7), (0.0, 10.0, 0.0), math.radians(60.0))
    with_ball, without = GrassField(far), GrassField(base)
    for field in (with_ball, without):
        field.seek(12, cam)
    lod = with_ball.lod(cam)
    blocks = np.flatnonzero(needs(BLADES, with_ball.layout, lod))
    assert np.array_equal(with_ball.blade_vertices(blocks, lod), without.blade_vertices(blocks, lod))
    assert with_ball.interaction.work == 0


def test_the_recovery_curve_holds_then_sways_back_to_rest():
    """R(0) = 1 (flat), slow rise to the release, a damped swing past upright (the paper's
    recovery: an underdamped blade overshoots), 0 from the recovery time on, no jumps."""
    recovery, w2, damping = 3.0, np.array([40.0]), np.array([2.0])
    tau = np.linspace(0.0, 4.0, 4001)
    r = interaction.recovery_curve(tau, recovery, np.full_like(tau, w2[0]), np.full_like(tau, damping[0]))
    assert r[0] == pytest.approx(1.0)
    assert np.all(np.diff(r[tau < interaction.HOLD * recovery]) <= 0)
    assert r.min() < -0.01  # the overshoot
    assert np.all(r[tau >= recovery] == 0.0)
    assert np.max(np.abs(np.diff(r))) < 0.02


def _effector_field(row):
    params = schema.loads_toml(BALL).replace({"interaction.colliders": [], "wind.speed": 0.0, "wind.turbulence": 0.0,
                                              "interaction.effectors": [row]})
    field = GrassField(params)
    cells = field.seek(24)
    return field, cells.bend.sum(axis=1)  # (C, 2): each cell's whole bend


def test_a_vortex_bends_the_grass_around_its_axis():
    field, bend = _effector_field({"type": "vortex", "strength": 8.0, "max_distance": 1.4})
    xy = field.layout.cell_center.astype(np.float64)
    r = np.hypot(xy[:, 0], xy[:, 1])
    within = (r > 0.3) & (r < 1.3) & (np.hypot(bend[:, 0], bend[:, 1]) > 1e-3)
    radial = xy[within] / r[within, None]
    b = bend[within] / np.hypot(bend[within, 0], bend[within, 1])[:, None]
    angle = np.degrees(np.arccos(np.clip(np.abs(np.sum(radial * b, axis=1)), 0.0, 1.0)))
    assert np.median(angle) > 80.0 and np.all(angle > 60.0), np.percentile(angle, [0, 50])
    # counter-clockwise seen from above for a positive strength: Z x r
    assert np.mean(radial[:, 0] * b[:, 1] - radial[:, 1] * b[:, 0]) > 0.9
    outside = r > 1.6
    assert np.abs(bend[outside]).max() < 1e-6  # nothing beyond max_distance


def test_a_wind_field_blows_along_its_z_axis_with_its_falloff():
    """A wind field at (-1, 0, 0.2) whose Z axis is turned to +X (rotation Y = 90 deg), falloff
    power 2: the grass bends along +X, less the farther it is from the field."""
    field, bend = _effector_field({"type": "wind", "position": [-1.0, 0.0, 0.2], "rotation": [0.0, 90.0, 0.0],
                                   "strength": 6.0, "falloff": 2.0})
    xy = field.layout.cell_center
    assert np.mean(bend[:, 0]) > 10 * np.mean(np.abs(bend[:, 1]))
    near = np.hypot(xy[:, 0] + 1.0, xy[:, 1]) < 0.3
    far = np.hypot(xy[:, 0] + 1.0, xy[:, 1]) > 2.0
    assert np.median(bend[near, 0]) > 2 * np.median(bend[far, 0]) > 0


def test_force_fields_are_computed_only_where_they_reach_with_the_same_wind():
    """A field with a maximum distance is evaluated at the cells within it only: the wind is the
    same as the wind plus each field's force at every cell (0 beyond its reach)."""
    rows = [{"type": "vortex", "position": [0.2, -0.3, 0.3], "strength": 6.0, "max_distance": 0.9, "noise": 0.5},
            {"type": "wind", "position": [-1.0, 0.5, 0.0], "rotation": [0.0, 80.0, 30.0], "strength": 4.0,
             "max_distance": 0.7},
            {"type": "force", "position": [1.0, 1.0, 0.5], "strength": -3.0, "max_distance": 1.2}]
    params = schema.loads_toml(BALL).replace({"interaction.colliders": [], "interaction.effectors": rows})
    field = GrassField(params)
    forced, layout = field.sim.wind, field.sim.layout
    points = np.column_stack([layout.cell_center, layout.cell_ground + 0.5 * layout.cell_length]).astype(np.float64)
    for t in (0.3, 1.7):
        everywhere = np.array(forced.wind.sample_layout(t, layout), dtype=np.float32)
        for e in forced.effectors.at(t):
            everywhere += forces.force(e, points, t)[:, :2].astype(np.float32)
        got = forced.sample_layout(t, layout)
        assert np.array_equal(got, everywhere)
        assert np.abs(got - forced.wind.sample_layout(t, layout)).max() > 0.5  # the fields blow


def test_blenders_falloff_law():
    """Blender's effector falloff: (1 + d - min)^-power, 1 inside the minimum, 0 past the maximum."""
    d = np.array([0.0, 0.5, 1.0, 3.0, 5.0])
    assert np.allclose(forces.falloff_law(d, False, 0.0, False, 0.0, 2.0), 1.0 / (1.0 + d) ** 2)
    out = forces.falloff_law(d, True, 1.0, True, 4.0, 1.0)
    assert np.allclose(out, [1.0, 1.0, 1.0, 1.0 / 3.0, 0.0])


@pytest.mark.parametrize("toml, key, words", [
    ("[[colliders]]\npath = [{time = 0.0, position = [0, 0, 0]}]", "interaction.colliders[0].path", "at least 2"),
    ("[[colliders]]\npath = [{time = 1.0, position = [0, 0, 0]}, {time = 0.5, position = [1, 0, 0]}]",
     "interaction.colliders[0].path", "not increasing"),
    ("[[effectors]]\ntype = \"magnet\"", "interaction.effectors[0].type", "wind"),
    ("[interaction]\nrecovery = 0.0", "interaction.recovery", "0.1 to 600 s"),
    ("[[colliders]]\nradius = 0.3\npath = [{time = 0.0, where = [0, 0, 0]}, {time = 1.0, position = [1, 0, 0]}]",
     "interaction.colliders[0].path[0]", "time = s, position"),
])
def test_bad_colliders_and_effectors_are_named(toml, key, words):
    with pytest.raises(ParameterError) as err:
        schema.loads_toml(toml)
    assert err.value.key == key and words in str(err.value), str(err.value)
