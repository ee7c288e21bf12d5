"""Deterministic time: the state at any frame, however it is reached (stepping, seeking, scrubbing).

* ``t(frame) = (frame - render.frame_start) / render.fps``.
* The simulation starts from rest at frame ``s0 = frame_start - round(simulation.preroll * fps)``;
  any frame ``<= s0`` shows that initial state.
* Going from frame ``f`` to ``f + 1`` samples the wind once, at ``t(f + 1)``, and runs one solver
  step of ``1 / fps`` seconds with ``solver.stable_substeps(1 / fps)`` sub-steps. So the state at
  frame N is a pure function of (params, wind, N): stepping 1..N, seeking straight to N and seeking
  back to N give bitwise identical arrays.
* Seeking backwards restores the nearest saved checkpoint ``<= frame`` and steps forward. A
  checkpoint is saved every ``simulation.checkpoint_interval`` frames from ``s0``; when their total
  memory passes ``max_checkpoint_bytes`` every other one is dropped (the interval doubles).
"""

from __future__ import annotations

import time

import numpy as np

from .solver import BladeSolver, SolverState

MAX_CHECKPOINT_BYTES = 1 << 30  # 1 GiB of saved states at most
PROGRESS_INTERVAL_S = 1.0


class Simulation:
    """The blade solver driven through time by a wind field (anything with ``sample(t)``)."""

    def __init__(self, layout, params, wind, max_checkpoint_bytes: int = MAX_CHECKPOINT_BYTES,
                 solver: BladeSolver | None = None):
        self.layout = layout
        self.params = params
        self.wind = wind
        self.fps = int(params.render.fps)
        self.frame_start = int(params.render.frame_start)
        self.frame_dt = 1.0 / self.fps
        self.start_frame = self.frame_start - int(round(params.simulation.preroll * self.fps))  # s0
        self.solver = solver if solver is not None else BladeSolver(layout, params)
        self.substeps = self.solver.stable_substeps(self.frame_dt)
        self.interval = int(params.simulation.checkpoint_interval)
        self.max_checkpoint_bytes = int(max_checkpoint_bytes)
        self._checkpoints: dict[int, SolverState] = {}
        self._wind_frame: int | None = None
        self._pos = self.start_frame  # the frame the solver's state belongs to
        self.frame = self.start_frame  # the frame last asked for (may be before the start)
        # progress(done, total) of a long seek: at most every PROGRESS_INTERVAL_S seconds, and
        # (total, total) at its end when it reported at all
        self.progress = None
        self.cell_wind = self._sample(self.frame)

    # ---------------------------------------------------------------------------- public API

    @property
    def state(self) -> SolverState:
        return self.solver.state

    def time(self, frame: int) -> float:
        """t(frame) in seconds: 0 at render.frame_start."""
        return (frame - self.frame_start) / self.fps

    def seek(self, frame: int) -> None:
        """Bring the state to ``frame`` (deterministic whichever way it gets there)."""
        frame = int(frame)
        target = max(frame, self.start_frame)  # frames before the start show the initial state
        if target != self._pos:
            best = max((f for f in self._checkpoints if f <= target), default=None)
            if target < self._pos or (best is not None and best > self._pos):
                # Backwards (or a checkpoint is nearer than the current frame): restore.
                if best is None:
                    self.solver.reset()
                    self._pos = self.start_frame
                else:
                    self.solver.state.assign(self._checkpoints[best])
                    self._pos = best
            begin, total, last_report = self._pos, target - self._pos, time.monotonic()
            reported = False
            while self._pos < target:
                self._step()
                if self.progress is not None and time.monotonic() - last_report >= PROGRESS_INTERVAL_S:
                    last_report, reported = time.monotonic(), True
                    self.progress(self._pos - begin, total)
            if reported:
                self.progress(total, total)  # the end of a seek that reported
        self.frame = frame
        if self._wind_frame != frame:
            self.cell_wind = self._sample(frame)

    # ---------------------------------------------------------------------------- internals

    def _sample(self, frame: int) -> np.ndarray:
        wind = np.ascontiguousarray(self.wind.sample(self.time(frame)), dtype=np.float32)
        self._wind_frame = frame
        return wind

    def _step(self) -> None:
        """One frame forward: wind at t(frame + 1), then the solver's sub-steps."""
        nxt = self._pos + 1
        self.cell_wind = self._sample(nxt)
        self.solver.step(self.cell_wind, self.frame_dt, self.substeps)
        self._pos = nxt
        if (nxt - self.start_frame) % self.interval == 0 and nxt not in self._checkpoints:
            self._save_checkpoint(nxt)

    def _save_checkpoint(self, frame: int) -> None:
        step = self.interval
        # Thinning: keep only multiples of the (doubled) spacing until the memory fits.
        size = self.solver.state.nbytes
        while (len(self._checkpoints) + 1) * size > self.max_checkpoint_bytes and self._checkpoints:
            step *= 2
            keep = {f: s for f, s in self._checkpoints.items() if (f - self.start_frame) % step == 0}
            if len(keep) == len(self._checkpoints):
                break
            self._checkpoints = keep
            self.interval = step
        if (frame - self.start_frame) % self.interval != 0:
            return
        if (len(self._checkpoints) + 1) * size > self.max_checkpoint_bytes:
            return
        self._checkpoints[frame] = self.solver.state.copy()

    @property
    def checkpoint_frames(self) -> list[int]:
        return sorted(self._checkpoints)
