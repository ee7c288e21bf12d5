"""Far grass sways with its patch: far grass is not simulated cell by cell (the paper's headline).

Blades, and the cards just beyond them, show each cell's own sway (``solver.py``, paper V.B). Farther
out a card is a few pixels tall: the cells of each GROUP x GROUP patch of a block show the sway of
the patch's first cell, its representative, and only the representatives are simulated there (a
sixteenth of the cells). Between the blades' end (``lod.blade_far``, scaled for the screen like
eq 7's distances) and BAND times as far, a cell's pose goes from its own to its representative's
(a ramp by its distance, as eq 7's), so the change is never a pop while the camera moves.

Every cell's pose stays a function of (settings, cell, frame, that frame's views): the solver steps
each cell on its own, so a representative has the same bits simulated with its block or alone; a
block is simulated cell by cell when any of its cells is nearer than the band's end (and stays so
while within KEEP times it: fewer catch-ups as the camera moves), and a block that joins either
set is caught up from its trajectories' starts (``Simulation.set_layout``).

``WindowSim`` is the window's simulation: ``Simulation``'s face for ``GrassField``, with ``look``
(the views of the frame about to be shown) choosing the blocks simulated cell by cell.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from .layout import cell_set
from .lod import block_distances, cell_distances, views_eyes
from .schema import Params
from .simulation import Simulation
from .solver import BladeSolver, SolverState, base_oscillator

GROUP = 4  # a far patch is GROUP x GROUP cells of a block, swaying as its first cell
BAND = 1.25  # the band where a cell's own sway gives way to its patch's ends at BAND x lod.blade_far
KEEP = 1.1  # a block simulated cell by cell stays so while within KEEP x the band's end
SPLIT_CELLS = 65_536  # a field of more cells is split; a smaller one (25.6 m at 0.1 m) steps every cell:
# its window is small, and catching blocks up as a camera moves would cost more than it saves
RAW_FRAMES = 4  # the simulations' poses kept for the frames around the shown one (motion blur)
F32 = np.float32


class Pose(SolverState):
    """What a frame shows of the window's cells: their bend and twist (``bend_t``, ``twist_t``
    and the public arrays). The rates and the equilibrium estimate belong to the simulations
    that step them; a pose has none (reading them is an error, never a zero)."""

    def __init__(self, n_cells: int, segments: int):  # (no super().__init__: no rates)
        self.bend_t = np.zeros((segments, 2, n_cells), dtype=F32)
        self.twist_t = np.zeros((segments, n_cells), dtype=F32)
        self.bend_vel_t = self.twist_vel_t = self.bend_eq_t = None  # type: ignore[assignment]
        self._views: dict[str, np.ndarray] = {}
        self._fresh: set[str] = set()
        self._lock = threading.Lock()

    def copy(self) -> Pose:
        out = Pose(self.n_cells, self.segments)
        np.copyto(out.bend_t, self.bend_t)
        np.copyto(out.twist_t, self.twist_t)
        return out


def patch_offsets(cells_per_block: int) -> tuple[np.ndarray, np.ndarray]:
    """For each cell of a block (row-major): the offset of its patch's representative in the
    block, and that representative's place among the block's representatives (``cell_offsets``)."""
    ly, lx = np.divmod(np.arange(cells_per_block * cells_per_block), cells_per_block)
    ry, rx = ly // GROUP, lx // GROUP
    side = -(-cells_per_block // GROUP)
    return (ry * GROUP) * cells_per_block + rx * GROUP, ry * side + rx


class WindowSim:
    """The cells of a window of blocks (``layout``) through time in ``wind``: the blocks near the
    views simulated cell by cell (``near``), the others by their patches' representatives
    (``far``); ``state`` and ``cell_wind`` are what the last ``seek`` shows."""

    def __init__(self, layout, params: Params, wind, near_ids=None):
        """``near_ids``: the blocks a run before this one simulated cell by cell for the views (a
        new run of an edit starts with them: no solver of the whole window is made); None: every
        block until ``look``."""
        self.params, self.wind, self.layout = params, wind, layout
        self._viewed = near_ids is not None  # a view chose them (else every block is near)
        ids = np.asarray(layout.block_ids)
        near_local, far_local = self._parts(ids if near_ids is None else ids[np.isin(ids, near_ids)])
        self.near = Simulation(self._near_layout(near_local, far_local), params, wind)
        self.far: Simulation | None = Simulation(cell_set(layout, far_local, GROUP), params, wind) \
            if far_local.size else None
        self.frame = self.near.frame
        self.state: SolverState = self.near.state
        self.cell_wind: np.ndarray = self.near.cell_wind
        self._near_ids = ids[near_local]  # field-wide ids simulated cell by cell
        self._index: np.ndarray | None = None  # (C,) each window cell's place in the joined poses
        self._base_index = np.zeros(0, np.int64)  # the same with every near cell its own
        self._near_cells = self._near_own = self._near_rep = np.zeros(0, np.int64)
        # (each window cell's place with the band's end applied; the band's cells in the window,
        # their own places, their patches' and (1, k) weights), or None when no cell is past blade_far
        self._band: tuple | None = None
        self._raw: OrderedDict[int, tuple] = OrderedDict()
        self._pose: Pose | None = None
        self._wind_shown: np.ndarray | None = None
        self._oscillator: tuple | None = None  # (window, recovery_oscillator's arrays)
        self._seen: tuple | None = None  # (window, eyes, scale) of the last look
        self._progress = None
        self._steps_done = 0  # steps of simulations let go
        self._index_cells(near_local, far_local)

    # ------------------------------------------------------------------ Simulation's face

    epoch = property(lambda self: self.near.epoch)
    fade = property(lambda self: self.near.fade)
    warmup = property(lambda self: self.near.warmup)
    frame_dt = property(lambda self: self.near.frame_dt)
    clock = property(lambda self: self.near.clock)
    fps = property(lambda self: self.near.fps)
    frame_start = property(lambda self: self.near.frame_start)
    loop = property(lambda self: self.near.loop)

    def time(self, frame: int) -> float:
        return self.near.time(frame)

    def epoch_of(self, frame: int) -> tuple[int, int]:
        return self.near.epoch_of(frame)

    def wind_at(self, frame: int, points: np.ndarray) -> np.ndarray:
        return self.near.wind_at(frame, points)

    @property
    def steps(self) -> int:
        """Cell-frames stepped so far (a measure of work)."""
        return self._steps_done + self.near.steps + (self.far.steps if self.far is not None else 0)

    @property
    def progress(self):
        return self._progress

    @progress.setter
    def progress(self, report) -> None:
        self._progress = self.near.progress = report
        if self.far is not None:
            self.far.progress = report

    @property
    def glimpse(self) -> int:
        """Frames of a first look's trajectories (``Simulation.glimpse``; 0: the run's own)."""
        return self.near.glimpse

    @glimpse.setter
    def glimpse(self, frames: int) -> None:
        for sim in (self.near, self.far):
            if sim is not None:
                sim.glimpse = frames

    @property
    def solver(self) -> BladeSolver:
        """The near simulation's solver (every cell's when every block is near)."""
        return self.near.solver

    def recovery_oscillator(self) -> tuple[np.ndarray, np.ndarray]:
        """(K/M, C/M) of each window cell's base joint (``BladeSolver.recovery_oscillator``)."""
        kept = self._oscillator
        if kept is None or kept[0] is not self.layout:
            kept = self._oscillator = (self.layout, base_oscillator(self.layout, self.params))
        return kept[1]

    # ------------------------------------------------------------------ which blocks are near

    def seen_near(self) -> np.ndarray | None:
        """The blocks simulated cell by cell for the last views (None: no view chose them)."""
        return self._near_ids if self._viewed else None

    def look(self, cameras, scale: float, frame: int | None = None) -> bool:
        """Choose the blocks simulated cell by cell for ``cameras`` (a list of ``lod.Camera``) with
        the LOD distances' ``scale``, and the band's weights. True when what ``seek`` shows of a
        frame changed (the poses kept for frames are then composed again)."""
        layout, lod = self.layout, self.params.lod
        eyes = views_eyes(cameras)
        seen = (layout, tuple(tuple(eye.tolist()) for eye in eyes), float(scale))
        if self._seen is not None and self._seen[0] is layout and self._seen[1:] == seen[1:]:
            return False  # (the same window from the same eyes: the same choice; a still camera's frames)
        self._seen = seen
        if not eyes or not self._splits(layout):
            return self._place(np.asarray(layout.block_ids), None, frame)
        self._viewed = True
        start = float(lod.blade_far) * float(scale)
        return self._place(self._chosen(layout, eyes, scale), (eyes, start, BAND * start), frame)

    def _splits(self, layout) -> bool:
        """Far blocks are simulated by patches: LOD on, a field of more than SPLIT_CELLS cells
        (the field's, not the window's: the choice never depends on the camera's path)."""
        grid = layout.grid
        return bool(self.params.lod.enabled and layout.n_blocks
                    and grid.n_blocks * grid.cells_per_block_total > SPLIT_CELLS)

    def _chosen(self, layout, eyes, scale: float) -> np.ndarray:
        """Ids of ``layout``'s blocks nearer ``eyes`` than the band's end, and those simulated cell
        by cell now that are within KEEP times it."""
        end = BAND * float(self.params.lod.blade_far) * float(scale)
        distance = block_distances(layout, eyes)
        near = (distance <= end) | ((distance <= KEEP * end) & np.isin(layout.block_ids, self._near_ids))
        return np.asarray(layout.block_ids)[near]

    def _place(self, ids: np.ndarray, band, frame: int | None) -> bool:
        """Simulate ``ids`` cell by cell; ``band`` (eyes, start, end): each near cell's weight
        from its distance (0 to ``start``, 1 from ``end``). True when anything shown changed."""
        changed = False
        if not np.array_equal(ids, self._near_ids):
            self._split(ids, frame)
            changed = True
        weights = None
        if band is not None and self._near_cells.size:
            eyes, start, end = band
            layout = self.layout
            d = cell_distances(layout.cell_center[self._near_cells], layout.cell_ground[self._near_cells], eyes)
            full = np.flatnonzero(d >= F32(end))  # (past the band: the patch's sway, its bits)
            part = np.flatnonzero((d > F32(start)) & (d < F32(end)))
            w = (d[part] - F32(start)) * F32(1.0 / (end - start)) if part.size else d[part]
            if full.size or part.size:
                index = self._base_index.copy()
                index[self._near_cells[full]] = self._near_rep[full]  # (past the band: the patch's sway)
                weights = (index, self._near_cells[part], self._near_own[part], self._near_rep[part],
                           w.astype(F32)[None, :])
        old = self._band
        if (old is None) != (weights is None) or (weights is not None and old is not None and not (
                np.array_equal(old[0], weights[0]) and np.array_equal(old[1], weights[1])
                and np.array_equal(old[4], weights[4]))):
            changed = True
        self._band = weights
        return changed

    def _parts(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(local ids simulated cell by cell: those of ``ids``, the others) of the window."""
        near = np.isin(self.layout.block_ids, ids)
        return np.flatnonzero(near), np.flatnonzero(~near)

    def _near_layout(self, near_local: np.ndarray, far_local: np.ndarray):
        """What the near simulation steps: the window itself when every block is near."""
        return self.layout if far_local.size == 0 else cell_set(self.layout, near_local)

    def _split(self, ids: np.ndarray, frame: int | None, renewed=()) -> None:
        """Simulate the blocks ``ids`` cell by cell, the rest of the window by representatives
        (``renewed``: blocks whose cells changed, caught up again: ``Simulation.set_layout``)."""
        near_local, far_local = self._parts(ids)
        self._near_ids = np.asarray(self.layout.block_ids)[near_local]
        self.near.set_layout(self._near_layout(near_local, far_local), frame=frame, renewed=renewed)
        if far_local.size:
            far_layout = cell_set(self.layout, far_local, GROUP)
            if self.far is None:
                self.far = Simulation(far_layout, self.params, self.wind)
                self.far.progress, self.far.glimpse = self._progress, self.near.glimpse
            else:
                self.far.set_layout(far_layout, frame=frame, renewed=renewed)
        elif self.far is not None:
            self._steps_done += self.far.steps
            self.far = None
        self._index_cells(near_local, far_local)
        self._raw.clear()

    def _index_cells(self, near_local: np.ndarray, far_local: np.ndarray) -> None:
        """Each window cell's place in the simulated cells joined (the near simulation's, then the
        far one's): its own, or its patch's first cell's; and the near cells' own and patch places."""
        layout = self.layout
        cpb = layout.cells_per_block
        rep_offset, rep_rank = patch_offsets(cpb)
        cells = layout.block_cells
        near_window = cells[near_local]
        everything = far_local.size == 0
        own = near_window if everything else np.arange(near_window.size).reshape(near_window.shape)
        index = np.empty(layout.n_cells, np.int64)
        index[near_window] = own
        side = -(-cpb // GROUP)
        index[cells[far_local]] = near_window.size + (np.arange(far_local.size)[:, None] * side * side
                                                      + rep_rank[None, :])
        self._near_cells, self._near_own = near_window.ravel(), own.ravel()
        self._near_rep = own[:, rep_offset].ravel()
        self._base_index = index
        self._index = None if everything else index

    # ------------------------------------------------------------------ time

    def seek(self, frame: int) -> None:
        """Bring the shown pose to ``frame`` (deterministic whichever way it gets there)."""
        frame = int(frame)
        if self._index is None and self._band is None:  # every block near, none in the band: as simulated
            self.near.seek(frame)
            self.state, self.cell_wind, self.frame = self.near.state, self.near.cell_wind, frame
            return
        raw = self._raw.get(frame)
        if raw is None:
            raw = self._simulated(frame)
            self._raw[frame] = raw
            while len(self._raw) > RAW_FRAMES:
                self._raw.popitem(last=False)
        self._compose(raw)
        self.frame = frame

    def _simulated(self, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(bend (2n, m), twist (n, m), wind (m, 2)) of every simulated cell at ``frame``: the near
        simulation's cells, then the far one's."""
        sims = [self.near] + ([self.far] if self.far is not None else [])
        for sim in sims:
            sim.seek(frame)
        n = self.layout.segments
        bend = np.concatenate([s.state.bend_t.reshape(2 * n, -1) for s in sims], axis=1)
        twist = np.concatenate([s.state.twist_t for s in sims], axis=1)
        wind = np.concatenate([s.cell_wind for s in sims], axis=0)
        return bend, twist, wind

    def _compose(self, raw) -> None:
        """The window's pose from the simulated cells: each cell its own or its representative's,
        the band's cells between the two by their weight."""
        bend, twist, wind = raw
        layout = self.layout
        n, cells = layout.segments, layout.n_cells
        if self._pose is None or self._pose.n_cells != cells or self._pose.segments != n:
            self._pose, self._wind_shown = Pose(cells, n), np.empty((cells, 2), F32)
        pose, wind_shown = self._pose, self._wind_shown
        assert wind_shown is not None
        bend_shown = pose.bend_t.reshape(2 * n, cells)
        index = self._index if self._band is None else self._band[0]
        if index is None:
            np.copyto(bend_shown, bend)
            np.copyto(pose.twist_t, twist)
            np.copyto(wind_shown, wind)
        else:
            np.take(bend, index, axis=1, out=bend_shown)
            np.take(twist, index, axis=1, out=pose.twist_t)
            np.take(wind, index, axis=0, out=wind_shown)
        if self._band is not None and self._band[1].size:
            _, cols, own, rep, w = self._band
            for src, dst in ((bend, bend_shown), (twist, pose.twist_t)):
                mine, theirs = np.take(src, own, axis=1), np.take(src, rep, axis=1)
                theirs -= mine
                theirs *= w
                theirs += mine
                dst[:, cols] = theirs
            mine, theirs = np.take(wind, own, axis=0), np.take(wind, rep, axis=0)
            theirs -= mine
            theirs *= w.T
            theirs += mine
            wind_shown[cols] = theirs
        pose.changed()
        self.state, self.cell_wind = pose, wind_shown

    # ------------------------------------------------------------------ the window

    def set_layout(self, layout, frame: int | None = None, renewed=(), cameras=None, scale: float = 1.0) -> None:
        """Work on the window ``layout`` from now on (``Simulation.set_layout``): with ``cameras``
        (and the LOD distances' ``scale``) the blocks near them are simulated cell by cell at once
        (as ``look`` chooses); without, those simulated so stay so while in it, a new block is
        simulated by its representatives until the next ``look`` (every block while no view chose)."""
        if self.layout is layout:
            return
        self.layout = layout
        ids = np.asarray(layout.block_ids)
        eyes = views_eyes(cameras)
        if eyes and self._splits(layout):
            self._viewed = True
            near = self._chosen(layout, eyes, scale)
        else:
            near = ids[np.isin(ids, self._near_ids)] if self._viewed else ids
        self._split(near, frame, renewed)
        self._band = None

    def retitle(self, layout) -> None:
        """The same blocks and cells with other settings of their look or level of detail
        (``FieldLayout.retitled``): the runs go on."""
        if not np.array_equal(layout.block_ids, self.layout.block_ids):
            raise ValueError("retitle: the layout must hold the same blocks (set_layout moves a window)")
        self.layout, self.params = layout, layout.params
        near_local, far_local = self._parts(self._near_ids)
        self.near.retitle(self._near_layout(near_local, far_local))
        if self.far is not None:
            self.far.retitle(cell_set(layout, far_local, GROUP))
