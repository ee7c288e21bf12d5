"""Deterministic time with bounded history (epochs, warm-up, cross-fade) and the shared cell data of eqs 33-34."""

import math

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.blade import GROUND_TILT
from windgrass.grass_addon.celldata import card_offset, cell_data
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.simulation import Simulation, fade_weight, seek_cost_bound
from windgrass.grass_addon.wind import WindField

BASE = {"field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 4, "render.fps": 24,
        "render.frame_start": 1, "simulation.preroll": 0.5}


class GustyWind:
    """A small stand-in wind (anything with sample(t) drives a Simulation): a smooth, varying
    gust along +X, different in every cell."""

    def __init__(self, n_cells):
        self.phase = np.linspace(0.0, 3.0, n_cells)

    def sample(self, t, xy=None):
        speed = 5.0 + 3.0 * np.sin(2.0 * t + self.phase)
        out = np.zeros((self.phase.size, 2), dtype=np.float32)
        out[:, 0] = speed
        out[:, 1] = 0.5 * np.cos(3.0 * t + self.phase)
        return out


def make(overrides=None, wind="field", **kw):
    params = schema.defaults().replace({**BASE, **(overrides or {})})
    layout = build_layout(params)
    field = WindField(layout, params) if wind == "field" else GustyWind(layout.n_cells)
    return layout, params, Simulation(layout, params, field, **kw)


def test_time_epochs_and_trajectory_starts():
    _, params, sim = make({"render.frame_start": 10, "render.fps": 25, "simulation.preroll": 2.0,
                           "simulation.epoch": 4.0})
    assert sim.time(10) == 0.0 and sim.time(35) == pytest.approx(1.0) and sim.time(5) == pytest.approx(-0.2)
    assert (sim.epoch, sim.warmup, sim.fade) == (100, 50, 25)
    assert sim.epoch_of(10) == (0, 0) and sim.epoch_of(109) == (0, 99) and sim.epoch_of(110) == (1, 0)
    assert sim.epoch_of(9) == (-1, 99)  # frames before the first have epochs too
    assert sim.trajectory_start(0) == 10 - 50  # from rest at t = -preroll
    assert sim.trajectory_start(3) == 10 + 300 - 50


def test_the_cross_fade_is_smooth_and_complete():
    epoch, fade = 100, 25
    weights = [fade_weight(r, epoch, fade) for r in range(epoch)]
    assert weights[: epoch - fade] == [0.0] * (epoch - fade)
    assert all(0.0 < w < 1.0 for w in weights[epoch - fade:])
    assert np.all(np.diff(weights) >= 0.0)
    assert max(np.diff(weights)) < 2.0 / fade  # no jump: a smoothstep over the fade
    assert weights[-1] > 0.9  # and the next epoch's frame 0 shows the next trajectory alone


def test_preroll_bends_the_grass_before_the_first_frame():
    _, params, sim = make({"simulation.preroll": 2.0}, wind="gusty")
    sim.seek(params.render.frame_start)
    assert np.degrees(np.linalg.norm(sim.state.bend.sum(axis=1), axis=1)).mean() > 10.0


@pytest.mark.parametrize("wind", ["field", "gusty"])
def test_state_is_the_same_whichever_path_reaches_a_frame(wind):
    """Stepping frame by frame through two epoch hand-overs, seeking straight to the frame, and
    seeking there after jumps back and forth give bitwise the same state."""
    overrides = {"simulation.preroll": 0.5, "simulation.epoch": 1.0}  # 12 and 24 frames
    _, _, stepped = make(overrides, wind=wind)
    target = 69  # epoch 2, frame 20: inside its cross-fade (frames 18-23 of 24)
    assert stepped.epoch_of(target)[1] >= stepped.epoch - stepped.fade
    for frame in range(-30, target + 1):
        stepped.seek(frame)
    reference = stepped.state.copy()
    reference_wind = stepped.cell_wind.copy()

    _, _, direct = make(overrides, wind=wind)
    direct.seek(target)
    assert direct.state.equals(reference)
    assert np.array_equal(direct.cell_wind, reference_wind)

    for frame in (target + 17, 13, target, -500, 5, target - 1, target):
        stepped.seek(frame)
    assert stepped.frame == target
    assert stepped.state.equals(reference)
    assert np.array_equal(stepped.state.bend, reference.bend)  # the public arrays too


def test_any_frame_costs_a_bounded_number_of_steps():
    """Reaching frame 100,000 steps no more than W + E + W frames, like frame 1; a seek back
    inside the same trajectory restores a saved state instead of starting again."""
    layout, params, sim = make(wind="gusty")
    bound = seek_cost_bound(params)
    for frame in (1, 100_000, 100_000 + sim.epoch - 1, -7_777):
        fresh = Simulation(layout, params, GustyWind(layout.n_cells))
        fresh.seek(frame)
        assert fresh.steps <= bound * layout.n_cells, frame
    sim.seek(60)
    before = sim.steps
    sim.seek(50)
    assert sim.steps - before < (50 - sim.trajectory_start(sim.epoch_of(50)[0])) * layout.n_cells


def test_cell_wind_is_the_wind_of_the_current_frame():
    layout, params, sim = make()
    other = WindField(layout, params)
    for frame in (12, 3, 30, -80):
        sim.seek(frame)
        assert np.array_equal(sim.cell_wind, other.sample(sim.time(frame)))
        assert sim.cell_wind.shape == (layout.n_cells, 2) and sim.cell_wind.dtype == np.float32


def test_card_offset_follows_eq_34():
    layout, _, sim = make(wind="gusty")
    sim.seek(20)
    data = cell_data(layout, sim)
    assert data.bend is sim.state.bend and data.twist is sim.state.twist  # shared, not copied
    assert data.wind is sim.cell_wind
    L = layout.card_height
    total = sim.state.bend.sum(axis=1)  # (n_cells, 2) the sum of the bends
    omega = np.linalg.norm(total, axis=1)
    off = data.card_offset
    assert off.shape == (layout.n_cells, 3) and off.dtype == np.float32
    total /= omega[:, None]  # Normal(V)
    omega = np.minimum(omega, GROUND_TILT)  # the ground stops the card's top
    # |horizontal| = L sin(omega), vertical = L cos(omega) - L (eq 34, Z up)
    assert np.allclose(np.linalg.norm(off[:, :2], axis=1), L * np.sin(omega), atol=1e-5)
    assert np.allclose(off[:, 2], L * np.cos(omega) - L, atol=1e-5)
    # horizontal direction = Normal(V): the summed bend's direction, i.e. along the wind
    direction = off[:, :2] / np.linalg.norm(off[:, :2], axis=1, keepdims=True)
    assert np.allclose(direction, total, atol=1e-4)
    # the card's top stays on a circle of radius L around its bottom edge: a rotation, no stretch
    top = off + np.stack([np.zeros_like(L), np.zeros_like(L), L], axis=1)
    assert np.allclose(np.linalg.norm(top, axis=1), L, atol=1e-5)


def test_card_offset_at_rest_and_at_a_right_angle():
    L = np.array([0.3, 0.5], dtype=np.float32)
    at_rest = card_offset(L, np.zeros((2, 2), dtype=np.float32))
    assert np.array_equal(at_rest, np.zeros((2, 3), dtype=np.float32))
    flat = card_offset(L, np.array([[0.0, math.pi / 2], [math.pi / 2, 0.0]], dtype=np.float32))
    # omega = 90 degrees: the top moves L sideways (first cell along +Y, second along +X) and L down,
    # stopped just above the ground (the ground tilt, a hair short of lying flat)
    s, c = math.sin(GROUND_TILT), math.cos(GROUND_TILT)
    assert np.allclose(flat, [[0.0, 0.3 * s, 0.3 * c - 0.3], [0.5 * s, 0.0, 0.5 * c - 0.5]], atol=1e-6)
    assert np.all(L + flat[:, 2] > 0.0)


def test_a_long_seek_reports_its_progress(monkeypatch):
    from windgrass.grass_addon import simulation as simulation_mod

    params = schema.defaults().replace({"field.blocks_x": 1, "field.blocks_y": 1, "field.cells_per_block": 4})
    layout = build_layout(params)
    sim = Simulation(layout, params, WindField(layout, params))
    calls = []
    sim.progress = lambda done, total: calls.append((done, total))
    monkeypatch.setattr(simulation_mod, "PROGRESS_INTERVAL_S", 0.0)  # report at every step
    sim.seek(30)
    total = 30 - sim.trajectory_start(0)
    assert calls[-1] == (total, total) and [d for d, _ in calls[:-1]] == list(range(1, total + 1))
    calls.clear()
    monkeypatch.setattr(simulation_mod, "PROGRESS_INTERVAL_S", 3600.0)  # a short seek says nothing
    sim.seek(31)
    assert calls == []


def test_high_frame_rates_say_what_a_seek_costs():
    """Issue: a seek at 240 fps cost 26.6 s against 2.6 s at 24 fps without a word: the warm-up
    and the epoch are seconds, so their frames grow with the frame rate. It is said (panel,
    render_field.py), with what makes it cheaper."""
    from windgrass.grass_addon.simulation import seek_note

    assert seek_note(schema.defaults()) is None
    fast = schema.defaults().replace({"render.fps": 240})
    note = seek_note(fast)
    assert f"{seek_cost_bound(fast):,} frames" in note and "10 times" in note and "simulation.preroll" in note
    assert seek_cost_bound(fast) == 10 * seek_cost_bound(schema.defaults())
