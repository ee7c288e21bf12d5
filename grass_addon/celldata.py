"""Data every representation of a cell shares, and the card deformation (paper V.B, eqs 33-34).

Blades and cards of a cell share the cell's bend and twist (paper V.B), so a blade strip near
the camera and the card that replaces it farther away move together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(eq=False)
class CellData:
    bend: np.ndarray  # (n_cells, n, 2) float32: each joint's bend vector (solver.py)
    twist: np.ndarray  # (n_cells, n) float32: each joint's twist (solver.py)
    wind: np.ndarray  # (n_cells, 2) float32: wind of the current frame, m/s
    card_offset: np.ndarray  # (n_cells, 3) float32: M' of eq 34, displacement of the card's top edge


def card_offset(card_height: np.ndarray, bend_sum: np.ndarray) -> np.ndarray:
    """M' of eq 34 in Blender's Z-up axes, (n_cells, 3) float32.

    card_height: (n_cells,) L, the card's height. bend_sum: (2, n_cells) the sum of the cell's
    bend vectors. omega = |bend_sum| is eq 33's "sum of the bending angle of each segment";
    Normal(V) is the direction of that summed bend vector. While the wind blows it is the wind
    direction (the solver bends along the wind), but unlike the raw wind it stays defined when
    the wind drops and swings back with the blade during recovery, so the card sways back too.
    Eq 34 is written Y-up, (L sin w Nx, L cos w - L, L sin w Ny); with Z up it reads
    (L sin w Nx, L sin w Ny, L cos w - L).
    """
    L = np.asarray(card_height, dtype=np.float32)
    sx, sy = bend_sum[0], bend_sum[1]
    omega = np.sqrt(sx * sx + sy * sy)
    # L sin(w) * (s / w): s / w is Normal(V); where w = 0 the offset is 0 (s = 0).
    scale = L * np.sin(omega) / np.maximum(omega, np.float32(1e-20))
    out = np.empty((L.shape[0], 3), dtype=np.float32)
    np.multiply(scale, sx, out=out[:, 0])
    np.multiply(scale, sy, out=out[:, 1])
    half = np.sin(0.5 * omega)
    np.multiply(np.float32(-2.0) * L, half * half, out=out[:, 2])  # L cos w - L = -2 L sin^2(w/2)
    return out


def cell_data(layout, sim) -> CellData:
    """The shared data of the simulation's current frame; bend/twist/wind are views (no copy)."""
    state = sim.state
    bend_sum = np.add.reduce(state.bend_t, axis=0)  # (2, n_cells), joint-major: contiguous rows
    return CellData(bend=state.bend, twist=state.twist, wind=sim.cell_wind,
                    card_offset=card_offset(layout.card_height, bend_sum))
