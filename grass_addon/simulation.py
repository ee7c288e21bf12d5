"""Deterministic time with bounded history: the state at any frame from a bounded number of steps.

* ``t(frame) = (frame - render.frame_start) * render.fps_base / render.fps`` (``clock.Clock``).
* Time is cut into epochs of ``E = simulation.epoch * fps`` frames from ``frame_start``. Each
  epoch ``k`` has its own trajectory: the solver started from rest at frame
  ``s_k = frame_start + k E - W`` (``W = simulation.preroll * fps``, the warm-up) and stepped one
  frame at a time, with the wind sampled once per frame at ``t(f + 1)`` for the step ``f -> f + 1``.
* Frame N of epoch k shows trajectory k; over the last ``F = W / 2`` frames of the epoch it
  cross-fades (smoothstep) into trajectory k + 1, which has run for at least ``W - F`` frames by
  then. The damped recovery of eqs 29-32 forgets its start within seconds, so the two agree
  closely and the hand-over does not pop.
* So the state of a cell at frame N is a pure function of (params, wind, N, cell): a trajectory
  starts at a fixed frame from rest and every cell is stepped on its own (the solver is per cell),
  whether the frames were stepped one by one, seeked to, or the cell joined the window later
  (``set_layout`` catches new cells up on their own). Reaching any frame costs at most
  ``W + E`` steps of one trajectory plus ``W`` of the next, never N.
* Seeking backwards within a trajectory restores the nearest saved state (one every
  ``CHECKPOINT_FRAMES`` frames, while the trajectory and the window live).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .clock import Clock
from .errors import ParameterError
from .layout import subset_layout
from .loop import loop_frames, wind_frame
from .schema import Params
from .solver import STATE_ARRAYS, BladeSolver, SolverState

PROGRESS_INTERVAL_S = 1.0
CHECKPOINT_FRAMES = 24  # a saved state every this many frames, or every second at higher frame rates
GLIMPSE_STRIDE = 3  # frames a first look's step spans (``Simulation.glimpse``)
MAX_CHECKPOINT_BYTES = 1 << 27  # 128 MiB of saved states per trajectory at most (they only speed seeks back)


@dataclass(eq=False)
class Trajectory:
    """Epoch ``k``'s solver run: started from rest at frame ``start``; ``state`` is at ``pos``."""

    k: int
    start: int
    state: SolverState
    pos: int
    checkpoints: dict[int, SolverState] = field(default_factory=dict)


def epoch_frames(params: Params) -> tuple[int, int, int]:
    """(E, W, F): epoch length, warm-up and cross-fade in frames. With a loop of P frames
    (``loop.py``) the epoch is the divisor of P nearest ``simulation.epoch`` that holds the warm-up,
    so the trajectories come round with the loop."""
    clock = Clock.of(params)
    warmup = max(1, clock.frames(params.simulation.preroll))
    epoch = max(warmup, clock.frames(params.simulation.epoch))
    period = loop_frames(params)
    if period:
        divisors = [d for d in range(warmup, period + 1) if period % d == 0] or [period]
        epoch = min(divisors, key=lambda d: (abs(d - epoch), d))
    return epoch, warmup, max(1, warmup // 2)


def fade_weight(r: int, epoch: int, fade: int) -> float:
    """Weight of the next trajectory at frame ``r`` of an epoch: 0 until the last ``fade``
    frames, then a smoothstep that reaches 1 at the epoch's end (where the next one takes over)."""
    u = (r - (epoch - fade) + 1) / (fade + 1)
    if u <= 0.0:
        return 0.0
    u = min(u, 1.0)
    return u * u * (3.0 - 2.0 * u)


class Simulation:
    """The blade solver driven through time by a wind field (anything with ``sample(t, xy)``)
    over the cells of ``layout`` (the whole field or a window of blocks; see ``set_layout``)."""

    def __init__(self, layout, params: Params, wind, solver: BladeSolver | None = None):
        self.params = params
        self.wind = wind
        self.clock = Clock.of(params)
        self.fps, self.frame_start = self.clock.rate, self.clock.frame_start
        self.frame_dt = self.clock.dt
        self.epoch, self.warmup, self.fade = epoch_frames(params)
        self.loop = loop_frames(params)  # P: the wind's frames repeat after it (loop.py); 0: never
        self.layout = layout
        self.solver = solver if solver is not None else BladeSolver(layout, params)
        self.substeps = self.solver.stable_substeps(self.frame_dt)
        self._trajectories: dict[int, Trajectory] = {}
        self._shown = SolverState(layout.n_cells, layout.segments)  # the cross-faded state
        self.frame = self.frame_start
        self.state: SolverState = self._shown
        self.cell_wind = self._sample(self.frame)
        self._wind_frame: int | None = self.frame
        self.steps = 0  # cell-frames stepped so far (a measure of work)
        # > 0: a first look (``GrassField.first_look``): each trajectory starts from rest this many
        # frames before the frame first asked of it, not at its s_k, and steps GLIMPSE_STRIDE frames
        # at a time (``_glance``): not the frames a build gives
        self.glimpse = 0
        # progress(done, total) of a long seek: at most every PROGRESS_INTERVAL_S seconds, and
        # (total, total) at its end when it reported at all
        self.progress: Callable[[int, int], None] | None = None

    # ---------------------------------------------------------------------------- public API

    def time(self, frame: int) -> float:
        """t(frame) in seconds: 0 at render.frame_start."""
        return self.clock.seconds(frame)

    def epoch_of(self, frame: int) -> tuple[int, int]:
        """(k, r): the epoch of ``frame`` and the frame's place in it."""
        k, r = divmod(int(frame) - self.frame_start, self.epoch)
        return k, r

    def trajectory_start(self, k: int) -> int:
        """s_k: the frame where trajectory k starts from rest."""
        return self.frame_start + k * self.epoch - self.warmup

    def seek(self, frame: int) -> None:
        """Bring the shown state to ``frame`` (deterministic whichever way it gets there)."""
        frame = int(frame)
        k, r = self.epoch_of(frame)
        weight = fade_weight(r, self.epoch, self.fade)
        wanted = [k] + ([k + 1] if frame >= self.trajectory_start(k + 1) else [])
        for old in [j for j in self._trajectories if j not in wanted]:
            del self._trajectories[old]
        self._advance({j: frame for j in wanted})
        if weight == 0.0:
            self.state = self._trajectories[k].state
        else:
            self._blend(self._trajectories[k].state, self._trajectories[k + 1].state, weight)
            self.state = self._shown
        self.frame = frame
        if self._wind_frame != frame:
            self.cell_wind = self._sample(frame)
            self._wind_frame = frame

    def retitle(self, layout) -> None:
        """Work on ``layout``, the blocks and cells of this one with other settings of their look or
        level of detail (``FieldLayout.retitled``): the run, its trajectories and the solver are kept."""
        if not np.array_equal(layout.block_ids, self.layout.block_ids):
            raise ValueError("retitle: the layout must hold the same blocks (set_layout moves a window)")
        self.layout = self.solver.layout = layout

    def set_layout(self, layout, frame: int | None = None, renewed=()) -> None:
        """Work on the cells of ``layout`` from now on (the whole field or a window of blocks;
        ``layout.block_ids``).

        Cells of blocks in both layouts keep their states; those of new blocks are stepped on
        their own from each live trajectory's start to its frame (the steps they would have
        taken in the window), so a cell's state never depends on when it joined. ``frame``: the
        frame about to be shown; trajectories it does not need are dropped, not caught up.
        ``renewed``: field-wide ids of blocks in both layouts whose cells changed (repainted
        lengths): they are caught up like new ones."""
        if self.layout is layout:
            return
        old = self.layout
        if frame is not None:
            k, _ = self.epoch_of(frame)
            for j in [j for j, t in self._trajectories.items() if j not in (k, k + 1) or t.pos > frame]:
                del self._trajectories[j]
        renewed = {int(b) for b in renewed}
        where = {int(b): i for i, b in enumerate(old.block_ids) if int(b) not in renewed}
        keep_new = [i for i, b in enumerate(layout.block_ids) if int(b) in where]
        keep_old = [where[int(layout.block_ids[i])] for i in keep_new]
        fresh = [i for i, b in enumerate(layout.block_ids) if int(b) not in where]
        new_cols = layout.block_cells[keep_new].ravel()
        old_cols = old.block_cells[keep_old].ravel()
        fresh_cols = layout.block_cells[fresh].ravel()
        self.layout = layout
        caught = self._catch_up(layout, fresh) if fresh and self._trajectories else {}
        for traj in self._trajectories.values():
            state = SolverState(layout.n_cells, layout.segments)
            for name in STATE_ARRAYS:
                dst, src = getattr(state, name), getattr(traj.state, name)
                dst[..., new_cols] = src[..., old_cols]
                if fresh:
                    dst[..., fresh_cols] = getattr(caught[traj.k], name)
            state.changed()
            traj.state = state
            traj.checkpoints.clear()
        self.solver = BladeSolver(layout, self.params)
        # blank until the next seek (which samples the wind of its frame for these cells)
        self._shown = SolverState(layout.n_cells, layout.segments)
        self.state = self._shown
        self.cell_wind = np.zeros((layout.n_cells, 2), np.float32)
        self._wind_frame = None

    # ---------------------------------------------------------------------------- internals

    def _catch_up(self, layout, fresh: list[int]) -> dict[int, SolverState]:
        """States of the cells of ``layout``'s local blocks ``fresh`` in every live trajectory,
        each stepped from the trajectory's start on its own."""
        sub = subset_layout(layout, fresh)
        runner = Simulation(sub, self.params, self.wind)
        out = {}
        for k, traj in self._trajectories.items():
            runner._trajectories.clear()
            runner._advance({k: traj.pos})
            out[k] = runner._trajectories[k].state
        self.steps += runner.steps
        return out

    def _sample(self, frame: int) -> np.ndarray:
        t = self.time(wind_frame(frame, self.frame_start, self.loop))  # (with a loop: its place in the first loop)
        by_layout = getattr(self.wind, "sample_layout", None)  # a WindField; a plain sampler also works
        wind = by_layout(t, self.layout) if by_layout is not None else self.wind.sample(t, self.layout.cell_center)
        return np.ascontiguousarray(wind, dtype=np.float32)

    def wind_at(self, frame: int, points: np.ndarray) -> np.ndarray:
        """The wind the grass is stepped with at ``frame`` (as ``_sample``, with the force fields),
        at ``points`` (m, 3): (m, 2) float32 m/s (``wind_map``)."""
        t = self.time(wind_frame(frame, self.frame_start, self.loop))
        by_points = getattr(self.wind, "sample_points", None)  # a ForcedWind: the force fields too
        wind = by_points(t, points) if by_points is not None else self.wind.sample(t, points[:, :2])
        return np.ascontiguousarray(wind, dtype=np.float32)

    def _trajectory(self, k: int, frame: int) -> Trajectory:
        """Trajectory k at a frame <= ``frame`` (restarted or restored when it is past it)."""
        traj = self._trajectories.get(k)
        if traj is not None and traj.pos <= frame:
            return traj
        start = self.trajectory_start(k)
        if self.glimpse > 0:
            start = max(start, frame - self.glimpse)
        if traj is None:
            traj = Trajectory(k, start, SolverState(self.layout.n_cells, self.layout.segments), start)
            self._trajectories[k] = traj
        best = max((f for f in traj.checkpoints if f <= frame), default=None)
        if best is None:
            traj.state.reset()
            traj.pos = start
        else:
            traj.state.assign(traj.checkpoints[best])
            traj.pos = best
        return traj

    def _advance(self, targets: dict[int, int]) -> None:
        """Step trajectories ``k`` to frames ``targets[k]`` together: one wind sample per frame."""
        if self.glimpse > 0:
            self._glance(targets)
            return
        trajs = [self._trajectory(k, f) for k, f in targets.items()]
        frames = [max(f, t.start) for t, f in zip(trajs, targets.values())]
        total = sum(f - t.pos for t, f in zip(trajs, frames))
        done, last_report, reported = 0, time.monotonic(), False
        while True:
            behind = [t for t, f in zip(trajs, frames) if t.pos < f]
            if not behind:
                break
            nxt = min(t.pos for t in behind) + 1
            wind = self._sample(nxt)
            self._wind_frame = nxt
            self.cell_wind = wind
            for traj in behind:
                if traj.pos == nxt - 1:
                    self._step(traj, wind)
                    done += 1
            if self.progress is not None and time.monotonic() - last_report >= PROGRESS_INTERVAL_S:
                last_report, reported = time.monotonic(), True
                self.progress(done, total)
        if reported and self.progress is not None:
            self.progress(total, total)

    def _glance(self, targets: dict[int, int]) -> None:
        """``_advance`` for a first look (``glimpse``): each trajectory stepped GLIMPSE_STRIDE
        frames at a time in the wind of each step's end: a third of the steps, and the blades' mean
        bend within a few per cent of the frame-by-frame run's (the solver's smooth update, eqs
        25-27, is exact for any step; joints too quick for the longer step follow it)."""
        for k, frame in targets.items():
            traj = self._trajectory(k, frame)
            while traj.pos < frame:
                stride = min(GLIMPSE_STRIDE, frame - traj.pos)
                wind = self._sample(traj.pos + stride)
                dt = stride * self.frame_dt
                self.solver.state = traj.state
                self.solver.step(wind, dt, self.solver.stable_substeps(dt))
                traj.pos += stride
                self.steps += self.layout.n_cells
                self._wind_frame, self.cell_wind = traj.pos, wind

    def _step(self, traj: Trajectory, wind: np.ndarray) -> None:
        self.solver.state = traj.state
        self.solver.step(wind, self.frame_dt, self.substeps)
        traj.pos += 1
        self.steps += self.layout.n_cells
        if (traj.pos - traj.start) % max(CHECKPOINT_FRAMES, round(self.fps)) == 0 and traj.pos not in traj.checkpoints:
            if (len(traj.checkpoints) + 1) * traj.state.nbytes <= MAX_CHECKPOINT_BYTES:
                traj.checkpoints[traj.pos] = traj.state.copy()

    def _blend(self, a: SolverState, b: SolverState, weight: float) -> None:
        """The shown state: (1 - w) a + w b, array by array."""
        w = np.float32(weight)
        for name in STATE_ARRAYS:
            out = getattr(self._shown, name)
            np.subtract(getattr(b, name), getattr(a, name), out=out)
            out *= w
            out += getattr(a, name)
        self._shown.changed()


def seek_note(params: Params) -> str | None:
    """What a jump to any frame costs at a high frame rate (None at 60 fps and below): the warm-up
    and the epoch are seconds, so their frames grow with the frame rate."""
    fps = Clock.of(params).rate
    if fps <= 60:
        return None
    frames = seek_cost_bound(params)
    return (f"at {fps:g} fps a jump to any frame simulates up to {frames:,} frames ({frames / fps:.0f} s of "
            f"wind), {fps / 24:.0f} times the work at 24 fps; shorter simulation.preroll and simulation.epoch "
            "make jumps cheaper")


def seek_cost_bound(params: Params) -> int:
    """Most trajectory-frames a seek to any frame steps: W + E of one trajectory, W of the next."""
    epoch, warmup, _ = epoch_frames(params)
    return warmup + epoch + warmup



MAX_SEEK_FRAMES = 20_000  # trajectory-frames one frame may cost (14 minutes of wind at 24 fps)


def check_seek(params: Params, frames) -> None:
    """ParameterError (naming simulation.epoch and its limit) when reaching a frame of ``frames``
    would simulate more than MAX_SEEK_FRAMES frames: a jump into a long epoch simulates from the
    epoch's start (issue #57: frame 1,000,000 with an epoch of 10^6 s simulated for minutes
    before anything said so). A frame near the scene's start costs its distance from it."""
    if not len(frames):
        return
    epoch, warmup, _ = epoch_frames(params)
    start = params.render.frame_start
    cost = min(seek_cost_bound(params), max(int(f) - start for f in frames) + 2 * warmup)
    if cost <= MAX_SEEK_FRAMES:
        return
    fps = Clock.of(params).rate
    longest = max(MAX_SEEK_FRAMES - 2 * warmup, 0) / fps
    raise ParameterError("simulation.epoch", f"{params.simulation.epoch:g} s: reaching frame {max(frames)} would "
                         f"simulate {cost:,} frames (valid: at most {MAX_SEEK_FRAMES:,}, a simulation.epoch of at most "
                         f"{longest:,.0f} s at {fps:g} fps with this preroll, or frames nearer render.frame_start)")
