"""The fast solver (grass_addon/solver.py) against the plain float64 statement of the equations
(solver_reference.py), cell by cell, frame by frame: they agree within float32 tolerance."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.solver import BladeSolver
from windgrass.grass_addon.wind import WindField

_spec = importlib.util.spec_from_file_location("solver_reference", Path(__file__).with_name("solver_reference.py"))
solver_reference = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(solver_reference)
ReferenceCell = solver_reference.ReferenceCell

FRAMES = 240
TOLERANCE = 1e-4  # rad, on angles up to about 1 rad: float32 rounding accumulated over 240 frames
SMALL = {"field.blocks_x": 2, "field.blocks_y": 1, "field.cells_per_block": 2}
# strong wind for 4 s, then none: the recovery swings (the oscillator of eqs 29-32)
DROP = [{"time": 0.0, "speed": 7.0, "direction": 30.0}, {"time": 4.0, "speed": 7.0, "direction": 30.0},
        {"time": 4.5, "speed": 0.0, "direction": 30.0}]


def compare(overrides: dict, fps: int = 24) -> tuple[float, float, bool]:
    params = schema.defaults().replace({**SMALL, **overrides})
    layout = build_layout(params)
    fast = BladeSolver(layout, params)
    wind = WindField(layout, params)
    cells = [ReferenceCell(layout, params, c) for c in range(layout.n_cells)]
    dt = 1.0 / fps
    substeps = fast.stable_substeps(dt)
    bend_error = twist_error = 0.0
    swung = False
    for frame in range(FRAMES):
        w = wind.sample(frame * dt)
        fast.step(w, dt, substeps)
        swung |= bool((fast.n_boundary < layout.segments).any())
        for c, cell in enumerate(cells):
            cell.step(w[c].astype(np.float64), dt, substeps)
        bend = np.stack([cell.bend for cell in cells])
        twist = np.stack([cell.twist for cell in cells])
        bend_error = max(bend_error, float(np.abs(fast.state.bend - bend).max()))
        twist_error = max(twist_error, float(np.abs(fast.state.twist - twist).max()))
    assert np.abs(bend).max() > 0.01 or overrides.get("wind.type") == "calm"  # the blades did bend
    return bend_error, twist_error, swung


@pytest.mark.parametrize("wind_type", schema.WIND_TYPES)
def test_every_wind_type_matches_the_reference(wind_type):
    bend_error, twist_error, _ = compare({"wind.type": wind_type})
    assert bend_error < TOLERANCE and twist_error < TOLERANCE


@pytest.mark.parametrize("fps, sub_steps", [(24, 1), (24, 4), (60, 1)])
def test_recovery_swings_match_the_reference(fps, sub_steps):
    bend_error, twist_error, swung = compare({"wind.keys": DROP, "simulation.sub_steps": sub_steps}, fps)
    assert swung  # the oscillating joints were exercised
    assert bend_error < TOLERANCE and twist_error < TOLERANCE
