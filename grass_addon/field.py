"""The engine facade: one grass field = layout + wind + simulation + LOD + kinematics.

Used by the add-on's runtime (one ``GrassField`` per field object) and by the headless scripts.
Everything heavy is built once in ``__init__``; the per-frame path (``seek``, ``lod``,
``blade_vertices``, ``card_vertices``) writes into caller-provided ``out`` arrays when given.
"""

from __future__ import annotations

import numpy as np

from . import kinematics
from .celldata import CellData, cell_data
from .layout import FieldLayout, build_layout
from .lod import Camera, LodWeights, lod_weights
from .schema import Params
from .simulation import Simulation
from .wind import WindField


class GrassField:
    """``GrassField(params, wind_keys=None, terrain=None)``; wind_keys: None (params.wind) or
    (time_s, speed, deg) rows; terrain: a ``terrain.Heightfield`` in the field's frame or None (flat)."""

    def __init__(self, params: Params, wind_keys=None, terrain=None):
        self.params = params
        self.layout: FieldLayout = build_layout(params, terrain=terrain)
        self.wind = WindField(self.layout, params, keys=wind_keys)
        self.sim = Simulation(self.layout, params, self.wind)
        self.cells: CellData | None = None  # cell data of the last seek
        self._blocks = np.arange(self.layout.n_blocks, dtype=np.int64)

    # ------------------------------------------------------------------ time

    @property
    def frame(self) -> int:
        return self.sim.frame

    def seek(self, frame: int) -> CellData:
        """Deterministic state at `frame` (a function of params, seed and frame only)."""
        self.sim.seek(int(frame))
        self.cells = cell_data(self.layout, self.sim)
        return self.cells

    def _current(self) -> CellData:
        if self.cells is None:
            self.cells = cell_data(self.layout, self.sim)
        return self.cells

    # ------------------------------------------------------------------ LOD

    def lod(self, camera: Camera | None) -> LodWeights:
        """Eqs 7-11 per cell and frustum culling per block (all geometry when camera is None)."""
        return lod_weights(self.layout, camera, self.params)

    def all_blocks(self) -> np.ndarray:
        """Every block id, 0 .. n_blocks-1 (read-only; do not modify)."""
        return self._blocks

    def blade_blocks(self, lod: LodWeights | None) -> np.ndarray:
        """Visible blocks that can hold blade geometry (some cell with N > 0); all when lod is None."""
        if lod is None:
            return self._blocks
        has_blades = (lod.blade_count[self.layout.block_cells] > 0).any(axis=1)
        return np.flatnonzero(lod.block_visible & has_blades)

    def card_blocks(self, lod: LodWeights | None) -> np.ndarray:
        """Visible blocks with some card opacity > 0; none when lod is None (all blades, no cards)."""
        if lod is None:
            return self._blocks[:0]
        has_cards = (lod.k_billboard[self.layout.block_cells] > 0).any(axis=1)
        return np.flatnonzero(lod.block_visible & has_cards)

    # ------------------------------------------------------------------ geometry

    def blade_vertices(self, blocks, lod: LodWeights | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """Blade strip vertices of `blocks` at the current frame; lod: hide blades beyond N (eq 9)."""
        counts = None if lod is None else lod.blade_count
        return kinematics.blade_vertices(self.layout, self._current(), blocks, counts, out)

    def card_vertices(self, blocks, out: np.ndarray | None = None) -> np.ndarray:
        """Card vertices of `blocks` at the current frame (paper III.B, eq 34)."""
        return kinematics.card_vertices(self.layout, self._current(), blocks, out)

    def blade_faces(self) -> np.ndarray:
        return kinematics.blade_faces(self.layout)

    def blade_uvs(self) -> np.ndarray:
        return kinematics.blade_uvs(self.layout)

    def card_faces(self) -> np.ndarray:
        return kinematics.card_faces(self.layout)

    def card_uvs(self) -> np.ndarray:
        return kinematics.card_uvs(self.layout)
