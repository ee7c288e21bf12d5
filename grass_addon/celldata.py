"""Data every representation of a cell shares, and the card deformation (paper V.B, eqs 33-34).

Blades and cards of a cell share the cell's bend and twist (paper V.B), so a blade strip near
the camera and the card that replaces it farther away move together.
"""

from __future__ import annotations

import numpy as np

from .blade import GROUND_TILT


class CellData:
    """The shared data of one frame (cell-major arrays, float32).

    bend (n_cells, n, 2): each joint's bend vector (solver.py); twist (n_cells, n): each joint's
    twist; wind (n_cells, 2) m/s; card_offset (n_cells, 3): M' of eq 34.
    bend_t (n, 2, n_cells) and twist_t (n, n_cells) are the same values joint-major (the solver's
    own layout, no copy) or None; kinematics reads them when present. When built by cell_data,
    bend and twist are the state's public arrays, transposed on first access only, and
    card_offset is computed on first access (a frame that draws no cards never pays for it).
    Like the state's arrays, they describe the state at the time of that access.
    """

    __slots__ = ("_bend", "_twist", "wind", "_card_offset", "bend_t", "twist_t", "_state", "_card_height")

    def __init__(self, bend=None, twist=None, wind=None, card_offset=None, *, bend_t=None, twist_t=None,
                 state=None, card_height=None):
        self._bend, self._twist, self.wind, self._card_offset = bend, twist, wind, card_offset
        self.bend_t, self.twist_t, self._state, self._card_height = bend_t, twist_t, state, card_height

    @property
    def bend(self) -> np.ndarray:
        return self._state.bend if self._bend is None and self._state is not None else self._bend

    @property
    def twist(self) -> np.ndarray:
        return self._state.twist if self._twist is None and self._state is not None else self._twist

    @property
    def card_offset(self) -> np.ndarray:
        if self._card_offset is None and self._card_height is not None and self.bend_t is not None:
            bend_sum = np.add.reduce(self.bend_t, axis=0)  # (2, n_cells), joint-major: contiguous rows
            self._card_offset = card_offset(self._card_height, bend_sum)
        return self._card_offset


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
    norm = np.sqrt(sx * sx + sy * sy)
    omega = np.minimum(norm, np.float32(GROUND_TILT))  # the ground stops the card's top too
    # L sin(w) * (s / |s|): s / |s| is Normal(V); where |s| = 0 the offset is 0 (s = 0).
    scale = L * np.sin(omega) / np.maximum(norm, np.float32(1e-20))
    out = np.empty((L.shape[0], 3), dtype=np.float32)
    np.multiply(scale, sx, out=out[:, 0])
    np.multiply(scale, sy, out=out[:, 1])
    half = np.sin(0.5 * omega)
    np.multiply(np.float32(-2.0) * L, half * half, out=out[:, 2])  # L cos w - L = -2 L sin^2(w/2)
    return out


def cell_data(layout, sim) -> CellData:
    """The shared data of the simulation's current frame; bend/twist/wind are views (no copy).

    bend and twist are the state's public (cell-major) arrays, transposed only when first read;
    bend_t/twist_t are the joint-major state arrays themselves; card_offset (eq 34) is computed
    when first read."""
    state = sim.state
    return CellData(wind=sim.cell_wind, bend_t=state.bend_t, twist_t=state.twist_t, state=state,
                    card_height=layout.card_height)
