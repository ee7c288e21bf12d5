"""The engine facade: one grass field = layout + wind + simulation + LOD + kinematics.

Used by the add-on's runtime (one ``GrassField`` per field object) and by the headless scripts.
Everything heavy is built once in ``__init__``; the per-frame path (``seek``, ``lod``,
``blade_vertices``, ``card_vertices``) writes into caller-provided ``out`` arrays when given.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from . import kinematics
from .celldata import CellData, cell_data
from .layout import FieldLayout, build_layout
from .lod import Camera, LodWeights, lod_weights
from .schema import Params
from .simulation import Simulation
from .wind import WindField

RECENT_FRAMES = 4  # states kept by cells_at (frames N - 1 .. N + 1, and the one before)


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
        self._recent: OrderedDict[int, CellData] = OrderedDict()  # states of frames around the shown one

    # ------------------------------------------------------------------ time

    @property
    def frame(self) -> int:
        return self.sim.frame

    def seek(self, frame: int) -> CellData:
        """Deterministic state at `frame` (a function of params, seed and frame only)."""
        self.sim.seek(int(frame))
        self.cells = cell_data(self.layout, self.sim)
        return self.cells

    def cells_at(self, frame: int) -> CellData:
        """Cell data of ``frame`` from its own copy of the state, kept with those of the few frames
        around it (motion blur reads frames N - 1, N and N + 1); deterministic like ``seek``."""
        frame = int(frame)
        cells = self._recent.get(frame)
        if cells is None:
            self.sim.seek(frame)
            state = self.sim.state.copy()
            cells = CellData(wind=self.sim.cell_wind.copy(), bend_t=state.bend_t, twist_t=state.twist_t,
                             state=state, card_height=self.layout.card_height)
            self._recent[frame] = cells
            while len(self._recent) > RECENT_FRAMES:
                self._recent.popitem(last=False)
        return cells

    def motion(self, frame: int, subframe: float, fps: float, vertices, out: np.ndarray, velocity: np.ndarray,
               ahead: np.ndarray) -> None:
        """Vertices at ``frame + subframe`` and their velocity in m/s, for motion blur.

        ``vertices(cells, out)`` writes the vertices of some blocks for cell data ``cells``; ``ahead``
        (shaped as ``out``) is scratch space for the later pose. The path
        through the frames' poses is piecewise linear: between frames the vertices move at the
        slope of their segment; at a whole frame the velocity is the central difference
        (P(N + 1) - P(N - 1)) fps / 2. Frames are computed in ascending order (cheap seeks)."""
        frame = int(frame)
        if subframe == 0.0:
            wanted = (frame - 1, frame, frame + 1)
        else:
            wanted = (frame, frame + 1)
        cells = [self.cells_at(f) for f in wanted]
        if subframe == 0.0:
            vertices(cells[0], velocity)  # P(N - 1)
            vertices(cells[2], ahead)  # P(N + 1)
            vertices(cells[1], out)  # P(N)
            np.subtract(ahead, velocity, out=velocity)
            velocity *= np.float32(0.5 * fps)
        else:
            vertices(cells[0], out)  # P(N)
            vertices(cells[1], ahead)  # P(N + 1)
            np.subtract(ahead, out, out=velocity)  # one frame's motion
            out += velocity * np.float32(subframe)
            velocity *= np.float32(fps)

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
