"""Bending, twisting and recovery of the per-cell blades (paper V.A, eqs 14-32)."""

import math

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon import solver as solver_mod
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.solver import BEND_LIMIT, TWIST_LIMIT, BladeSolver

FPS = 24
DT = 1.0 / FPS
SMALL = {"field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 4}


def make(overrides=None, **kw):
    params = schema.defaults().replace({**SMALL, **(overrides or {})})
    layout = build_layout(params)
    return layout, BladeSolver(layout, params, **kw)


def uniform(n_cells, speed, direction_deg=0.0):
    a = math.radians(direction_deg)
    wind = np.empty((n_cells, 2), dtype=np.float32)
    wind[:, 0] = speed * math.cos(a)
    wind[:, 1] = speed * math.sin(a)
    return wind


def run(sol, wind, frames, fps=FPS):
    m = sol.stable_substeps(1.0 / fps)
    for _ in range(frames):
        sol.step(wind, 1.0 / fps, m)


def total_bend(sol):
    """(n_cells, 2): the sum of the joints' bend vectors (tip deflection from the rest shape)."""
    return sol.state.bend.sum(axis=1)


@pytest.fixture(scope="module")
def default():
    return make()


def test_state_starts_at_rest_with_the_documented_layout(default):
    layout, sol = default
    sol.reset()
    st = sol.state
    n = layout.segments
    assert st.bend.shape == (layout.n_cells, n, 2) and st.bend.dtype == np.float32
    assert st.twist.shape == (layout.n_cells, n) and st.twist_vel.shape == (layout.n_cells, n)
    assert st.bend.flags["C_CONTIGUOUS"] and st.twist.flags["C_CONTIGUOUS"]
    assert not st.bend.any() and not st.twist.any()


def test_no_wind_keeps_the_rest_shape(default):
    layout, sol = default
    sol.reset()
    run(sol, uniform(layout.n_cells, 0.0), 24)
    assert not sol.state.bend.any() and not sol.state.twist.any()


@pytest.mark.parametrize("direction", [0.0, 40.0, 200.0])
def test_blades_bend_along_the_wind(default, direction):
    layout, sol = default
    sol.reset()
    run(sol, uniform(layout.n_cells, 5.0, direction), 3 * FPS)
    tot = total_bend(sol)
    angle = np.degrees(np.arctan2(tot[:, 1], tot[:, 0]))
    error = (angle - direction + 180.0) % 360.0 - 180.0
    # the wind torque is along the wind (eq 18), so the steady bend is too
    assert np.abs(error).max() < 3.0
    assert np.linalg.norm(tot, axis=1).min() > np.radians(5.0)


def test_stronger_wind_bends_more(default):
    layout, sol = default
    amounts = []
    for speed in (2.0, 4.4, 6.7, 10.0):
        sol.reset()
        wind = uniform(layout.n_cells, speed, 30.0)
        run(sol, wind, 2 * FPS)
        frames = []
        for _ in range(FPS):  # average over the last second: the upper blade may still sway
            run(sol, wind, 1)
            frames.append(np.linalg.norm(total_bend(sol), axis=1))
        amounts.append(np.mean(frames, axis=0))
    for weaker, stronger in zip(amounts[:3], amounts[1:3]):
        assert np.all(stronger > weaker)
    # in a strong wind a cell may settle on a different branch of the reconfigured statics
    # (segments laid past the horizontal lose lever), so only the field's mean is compared
    assert amounts[3].mean() > amounts[2].mean()
    # but the bend saturates: a blade laid along the wind catches less of it (sin phi of eq 17)
    assert np.degrees(amounts[-1].mean()) < 100.0


def test_gentle_breeze_bends_the_tip_visibly(default):
    # art direction of the defaults: a gentle breeze (4.4 m/s) bends a 0.32 m blade's tip by
    # roughly 20-45 degrees, a moderate breeze (6.7 m/s) clearly more
    layout, sol = default
    sol.reset()
    run(sol, uniform(layout.n_cells, 4.4), 3 * FPS)
    gentle = np.degrees(np.linalg.norm(total_bend(sol), axis=1).mean())
    sol.reset()
    run(sol, uniform(layout.n_cells, 6.7), 3 * FPS)
    moderate = np.degrees(np.linalg.norm(total_bend(sol), axis=1).mean())
    assert 20.0 < gentle < 45.0
    assert moderate > gentle + 8.0


def test_sudden_wind_change_stays_smooth_where_hookes_law_jumps(default):
    # Paper V.A: eq 6 alone jumps to the new equilibrium within one frame when the wind changes
    # suddenly; the three-step update (eqs 25-27) and the oscillator (eq 32) spread it out.
    layout, sol = default
    sol.reset()
    calm, storm = uniform(layout.n_cells, 0.0), uniform(layout.n_cells, 8.0)
    hooke_before = sol.equilibrium_bend(calm).sum(axis=1)
    hooke_after = sol.equilibrium_bend(storm).sum(axis=1)
    hooke_jump = hooke_after - hooke_before
    assert np.all(hooke_before == 0.0) and hooke_jump.min() > np.radians(30.0)

    previous = np.zeros(layout.n_cells)
    changes = []
    m = sol.stable_substeps(DT)
    for _ in range(2 * FPS):
        sol.step(storm, DT, m)
        now = np.linalg.norm(total_bend(sol), axis=1)
        changes.append(np.abs(now - previous))
        previous = now
    changes = np.array(changes)
    # the first frame moves a fraction of the Hooke jump; no frame moves more than about a third
    assert np.all(changes[0] < 0.7 * hooke_jump) and changes[0].mean() < 0.2 * hooke_jump.mean()
    assert changes.max(axis=0).mean() < 0.35 * hooke_jump.mean()
    # and the blade does settle into a bent pose (less than Hooke's: reconfiguration)
    assert np.all(changes[-3:] < np.radians(6.0))
    assert np.degrees(previous.mean()) > 30.0


def test_release_overshoots_then_decays_to_rest(default):
    # Paper V.A (2): when the wind stops the upper blade swings past the rest pose and sways
    # back and forth with decaying amplitude before it comes to rest.
    layout, sol = default
    sol.reset()
    direction = 30.0
    run(sol, uniform(layout.n_cells, 6.7, direction), 3 * FPS)
    w = np.array([math.cos(math.radians(direction)), math.sin(math.radians(direction))])
    steady = sol.state.bend[:, 2:, :].sum(axis=1) @ w  # upper joints, along the wind
    assert steady.min() > 0
    calm = uniform(layout.n_cells, 0.0)
    m = sol.stable_substeps(DT)
    trace = []
    for _ in range(4 * FPS):
        sol.step(calm, DT, m)
        trace.append(sol.state.bend[:, 2:, :].sum(axis=1) @ w)
    trace = np.array(trace)  # (frames, cells)
    mean = trace.mean(axis=1)
    # overshoot: the upper blade swings to the other side of the rest pose
    assert mean.min() < -0.15 * steady.mean()
    # in most cells (a short blade's stiff top may be too fast to sway at 24 fps: quasi-static)
    assert (trace.min(axis=0) < 0).mean() > 0.8
    # successive swing peaks decay
    extrema = [i for i in range(1, len(mean) - 1)
               if abs(mean[i]) >= abs(mean[i - 1]) and abs(mean[i]) >= abs(mean[i + 1])
               and abs(mean[i]) > 0.1 * steady.mean()]
    peaks = np.abs(mean[extrema])
    assert len(peaks) >= 2 and np.all(np.diff(peaks) < 0)
    # the sway is a visible 1-3 Hz one: the first swing back peaks 0.1-0.5 s after release
    first_negative_peak = int(np.argmin(mean[: FPS]))
    assert 2 <= first_negative_peak <= 12
    # back to (nearly) rest after four seconds
    assert np.abs(mean[-FPS:]).max() < 0.15 * steady.mean()


def test_boundary_frees_more_segments_far_from_equilibrium(default):
    # eq 28: n_boundary = n exp(-((1/2n) sum |dtheta| + |dphi|) - k) lambda): the farther from
    # equilibrium, the lower the boundary and the more (upper) segments oscillate
    layout, sol = default
    n = layout.segments
    calm = uniform(layout.n_cells, 0.0)
    sol.reset()
    sol.step(calm, DT, 1)
    assert np.all(sol.n_boundary == n)  # at rest and at equilibrium: nothing oscillates
    boundaries = []
    for angle in (0.01, 0.05, 0.2):
        sol.reset()
        sol.state.bend_t[:, 0, :] = angle  # bent along +X with no wind to hold it
        sol.state.changed()
        sol.step(calm, DT, 1)
        boundaries.append(sol.n_boundary.copy())
    assert np.all(boundaries[0] > boundaries[1]) and np.all(boundaries[1] > boundaries[2])
    k, lam = layout.params.blade.boundary_k, layout.params.blade.boundary_lambda
    expected = n * math.exp(-(0.2 * n / (2 * n) - k) * lam)  # the 0.2 rad deviation of each joint
    assert boundaries[2] == pytest.approx(np.full(layout.n_cells, expected), rel=1e-4)


def test_twist_turns_the_face_towards_broadside(default):
    # eqs 19-20: the twisting torque turns a face normal towards the wind line and vanishes
    # there, so the twist reduces the face-to-wind angle without passing it
    layout, sol = default
    sol.reset()
    direction = math.radians(10.0)
    wind = uniform(layout.n_cells, 6.7, 10.0)
    run(sol, wind, 2 * FPS)
    frames = []
    for _ in range(FPS):  # average over the last second: the upper blade may still sway
        run(sol, wind, 1)
        frames.append(sol.state.twist.sum(axis=1))
    delta = (direction - layout.cell_facing + 0.5 * np.pi) % np.pi - 0.5 * np.pi  # face normal to wind line
    tip_twist = np.mean(frames, axis=0)
    oblique = np.abs(delta) > np.radians(10.0)
    assert oblique.sum() > 5
    assert np.all(np.sign(tip_twist[oblique]) == np.sign(delta[oblique]))
    assert np.all(np.abs(tip_twist) <= np.abs(delta) + np.radians(3.0))  # swaying joints: a little past


def test_stable_substeps_respects_the_minimum_and_the_frame_rate():
    layout, sol = make()
    for fps in (1, 24, 240):
        assert 1 <= sol.stable_substeps(1.0 / fps) <= solver_mod.AUTO_MAX_SUBSTEPS
    # defaults at the paper's 24 fps stay cheap (performance budget of the per-frame solver)
    assert sol.stable_substeps(1.0 / 24) <= 2
    _, sol8 = make({"simulation.sub_steps": 8})
    assert sol8.stable_substeps(1.0 / 24) >= 8
    with pytest.raises(ValueError):
        sol.stable_substeps(0.0)


def test_wrong_wind_shape_is_refused(default):
    layout, sol = default
    with pytest.raises(ValueError, match="wind must have shape"):
        sol.step(np.zeros((layout.n_cells, 3), dtype=np.float32), DT)


def test_result_does_not_depend_on_chunking_or_threads():
    # every operation is per cell, so any split of the cells gives bitwise identical states
    params = schema.defaults().replace(SMALL)
    layout = build_layout(params)
    rng = np.random.default_rng([7, 1])
    winds = [(rng.normal(0.0, 4.0, (layout.n_cells, 2)) + [5.0, 2.0]).astype(np.float32) for _ in range(30)]
    states = []
    for chunk, threads in ((10_000, 1), (7, 2), (13, 3)):
        sol = BladeSolver(layout, params, chunk_cells=chunk, threads=threads)
        for w in winds:
            sol.step(w, DT, 2)
        for _ in range(10):
            sol.step(np.zeros_like(winds[0]), DT, 2)
        states.append(sol.state)
        sol.close()
    assert states[0].equals(states[1]) and states[0].equals(states[2])


@pytest.mark.parametrize("cells", [1, 2, 9, 128_768, 131_072, 131_073, 136_704, 400_001])
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_lanes_step_equal_shares_of_the_cells(cells, threads):
    # The window's cells over the engine's lanes: a frame waits for the slowest lane, so no lane
    # may step more than its share. 136,704 cells (the meadow at 100.8 m) were once cut
    # 65,536 + 65,536 + 5,632, and the lane with two chunks made the frame change 1.2x slower.
    chunks = solver_mod._balanced_chunks(cells, 65_536, threads)
    assert chunks[0][0] == 0 and chunks[-1][1] == cells
    assert all(a < b for a, b in chunks) and all(p[1] == q[0] for p, q in zip(chunks, chunks[1:]))
    assert max(b - a for a, b in chunks) <= 65_536
    lanes = min(threads, len(chunks))
    shares = [sum(b - a for a, b in chunks[i::lanes]) for i in range(lanes)]
    assert max(shares) - min(shares) <= len(chunks) // lanes, shares
    if cells >= threads:
        assert lanes == threads


def _extreme_configs():
    configs = []
    for p in schema.section_params("blade"):
        if p.kind in ("int", "float"):
            configs.append({p.name: p.minimum})
            configs.append({p.name: p.maximum})
    configs.append({"blade.root_stiffness": 1e-7, "blade.density": 1.0, "blade.damping_mass": 0.0,
                    "blade.damping_stiffness": 0.0, "blade.nonlinear_stiffness": 0.0})
    configs.append({"blade.root_stiffness": 1.0, "blade.density": 1e-5, "blade.damping_stiffness": 1.0,
                    "blade.nonlinear_stiffness": 1.0, "blade.response_torque": 1e-7})
    return configs


@pytest.mark.parametrize("fps", [1, 240])
@pytest.mark.parametrize("overrides", _extreme_configs(), ids=lambda o: ",".join(f"{k}={v:g}" for k, v in o.items()))
def test_extreme_parameters_stay_finite_and_bounded(overrides, fps):
    params = schema.defaults().replace({"field.blocks_x": 1, "field.blocks_y": 1, "field.cells_per_block": 3,
                                        "render.fps": fps, **overrides})
    layout = build_layout(params)
    sol = BladeSolver(layout, params)
    m = sol.stable_substeps(1.0 / fps)
    rng = np.random.default_rng([3, fps])
    frames = 30 if fps == 240 else 8
    for i in range(frames):
        speed = 60.0 if (i // 3) % 2 == 0 else 0.0  # storm and calm, switching abruptly
        wind = (speed * np.array([0.6, 0.8]) + rng.normal(0.0, 0.3 * speed + 1e-3, (layout.n_cells, 2)))
        sol.step(wind.astype(np.float32), 1.0 / fps, m)
        st = sol.state
        for arr in (st.bend, st.bend_vel, st.twist, st.twist_vel):
            assert np.all(np.isfinite(arr))
        assert np.abs(st.bend).max() <= BEND_LIMIT + 1e-6
        assert np.abs(st.twist).max() <= TWIST_LIMIT + 1e-6
    assert m <= max(params.simulation.sub_steps, solver_mod.AUTO_MAX_SUBSTEPS)


@pytest.mark.parametrize("wind_type", ["calm", "gentle_breeze", "blast"])
def test_stiff_damping_with_short_blades_stays_finite(wind_type):
    """Strong stiffness damping (beta of eq 31) with a wide spread of blade lengths: the short
    blades' joints are too stiff to sub-step, and must still not overflow into NaN."""
    params = schema.defaults().replace({"field.blocks_x": 2, "field.blocks_y": 2, "blade.damping_stiffness": 0.6,
                                        "wind.type": wind_type})
    params = params.replace({"blade.species": [{"name": "spread", "length_variation": 0.98}]})
    field = GrassField(params)
    for frame in (1, 12, 24):
        field.seek(frame)
        state = field.sim.state
        for name in ("bend_t", "bend_vel_t", "twist_t", "twist_vel_t", "bend_eq_t"):
            assert np.isfinite(getattr(state, name)).all(), (name, frame)
