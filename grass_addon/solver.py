"""Per-cell bending, twisting and recovery of grass in wind (paper V.A, eqs 14-32).

The solver is per cell (paper V.B: every blade of a cell shares the cell's bend and twist). The
representative blade of cell ``c`` is ``layout.cell_length/cell_width/cell_root_stiffness/
cell_rest_tilt/cell_facing``, split into ``n`` rigid segments; joint ``i`` (0-based) is the bottom
of segment ``i``.

State (rest = all zeros), angles in radians, relative to the rest shape of eqs 1-6:

* ``bend`` (n_cells, n, 2): each joint's bend as a tilt vector in the ground plane (X, Y): the
  direction the segment above the joint is pushed, magnitude = bend angle. Segment ``j``'s
  absolute tilt vector is ``T_j = cell_rest_tilt[c, j] * d_c + sum_{k<=j} bend[c, k]`` with
  ``d_c = (cos cell_facing, sin cell_facing)``; its axis is ``(sin|T| T/|T|, cos|T|)``.
* ``twist`` (n_cells, n): each joint's twist about the blade axis, cumulative like the bend:
  segment ``j``'s face normal points to azimuth ``cell_facing + sum_{k<=j} twist[c, k]``.
* ``bend_vel``, ``twist_vel``: their rates in rad/s.

One solver step (``step``, once per frame; the wind is sampled once per frame) runs four phases on
each chunk of cells (``_step_chunk``), each with named inputs and outputs:

1. ``_forcing`` (eqs 14-20) -> ``_Forcing``: the wind's bend and twist torques on the shape of the
   equilibrium estimate E (a state array, relaxed towards the reconfigured statics by one
   fixed-point iteration per step);
2. ``_equilibrium`` (eqs 21-24) -> ``_Equilibrium``: mu(t), the equilibrium bend M / mu(t) along the
   wind and twist, E moved towards them, the gaps E - theta and the swing amplitudes;
3. ``_boundary`` (eq 28) -> ``_Split``: n_boundary, and the joints above it that oscillate;
4. ``_smooth_fractions`` + ``_smooth_update`` (eqs 25-27) for the joints at or below n_boundary,
   ``_oscillate`` (eqs 29-32, ``substeps`` symplectic Euler steps) for those above it. Joints too
   stiff to show a sway at the frame rate always take the smooth update.
The twist follows the same split with a self-limiting equilibrium (the face turns towards
broadside to the wind, never past it; see ``_equilibrium``).

``tests/core/solver_reference.py`` states the same step plainly (float64, per cell, per joint);
the tests hold this one to it.

Performance: the work runs on joint-major arrays (component, joint, cell) so every numpy call
covers a long contiguous row of cells; loops only run over the n segments, never over cells. The
cells are cut into equal chunks, as many for each of the engine's two lanes (``workers.py``; numpy
releases the GIL; ``_balanced_chunks``); every operation is element-wise per cell, so the result is
bitwise identical however the cells are chunked. Each pass over the chunk's joints costs about as
much as the next, so the step makes few passes: preallocated scratch buffers (one quantity each,
named after it), ``out=`` everywhere, float32 scalars, constants folded at construction (l_length
into the wind area), the oscillator integrated in place on the gaps, and with one sub-step the
smooth update folded into the oscillator's per-joint coefficients instead of computed beside it and
blended.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from . import blade, workers
from .schema import Params

RHO_AIR = 1.225  # rho_wind of eqs 15-17, kg/m^3 (air at sea level, 15 C)
REFERENCE_DT = 1.0 / 24.0  # dt_ref: the paper's frame (24 fps) in which eq 26's rate M/gamma is given
BEND_LIMIT = 0.5 * math.pi  # physical bound of each component of a joint's bend (rad)
STIFFEN_LIMIT = 1.0  # |bend| (rad) beyond which eq 23's nonlinear stiffening stops growing
TWIST_LIMIT = 0.5 * math.pi - 0.05  # |twist| < pi/2: a face cannot turn past edge-on to its rest
AUTO_MAX_SUBSTEPS = 16  # stable_substeps never asks for more than this on its own
FRAMES_PER_SWAY = 5.5  # a joint swinging faster than one period per this many frames flickers
EPS = 1.0e-12
SMOOTH_MIN_ANGLE = 0.1  # rad: below this gap the smooth update's rate stops falling (eq 26)
# -log(1 - f) per unit of max(gap, SMOOTH_MIN_ANGLE) * twist_stiffness (>= 0.01) of a quasi-static
# joint: makes its smooth fraction f exactly 1 (exp(-1e3) underflows); see _step_chunk
QUASI_RATE = 1.0e6
RELAX_GAIN = 1.0  # slope of the reconfigured equilibrium per radian of the blade's bend (_step_chunk)

ONE_LANE_CELLS = 12_000  # fewer cells step faster on one lane than handed to two (far_sway's patches). The
# Add-menu field's 16,384 step faster on one lane in a script (3.5-5.3 against 6.0-6.4 ms), but an
# edit's run on a thread in Blender's window, beside the viewport's drawing, arrived later on one:
# the window test of a wind drag showed the grass of the speed before (stop 74); kept at 12,000
F32 = np.float32
ROW_PAD = 16  # floats between the rows of a scratch buffer (see _Scratch)


STATE_ARRAYS = ("bend_t", "bend_vel_t", "twist_t", "twist_vel_t", "bend_eq_t")


class SolverState:
    """The solver's state. Public arrays (cell-major, C-contiguous float32):

    ``bend`` (n_cells, n, 2), ``bend_vel`` (n_cells, n, 2), ``twist`` (n_cells, n), ``twist_vel``.
    Internally the state is joint-major (``*_t`` arrays: (n, 2, n_cells) and (n, n_cells)); the
    public arrays are transposed copies, refreshed in place on first access after a change
    (copy them to keep a frame's values).
    """

    def __init__(self, n_cells: int, segments: int):
        self.bend_t = np.zeros((segments, 2, n_cells), dtype=F32)
        self.bend_vel_t = np.zeros((segments, 2, n_cells), dtype=F32)
        self.twist_t = np.zeros((segments, n_cells), dtype=F32)
        self.twist_vel_t = np.zeros((segments, n_cells), dtype=F32)
        # The equilibrium estimate E whose shape the wind loads act on (see
        # BladeSolver._step_chunk); part of the state so that every path to a frame agrees.
        self.bend_eq_t = np.zeros((segments, 2, n_cells), dtype=F32)
        self._views: dict[str, np.ndarray] = {}
        self._fresh: set[str] = set()
        self._lock = threading.Lock()

    @property
    def n_cells(self) -> int:
        return self.twist_t.shape[1]

    @property
    def segments(self) -> int:
        return self.twist_t.shape[0]

    def changed(self) -> None:
        """Mark the public copies stale (call after writing the ``*_t`` arrays)."""
        self._fresh = set()

    def _public(self, name: str) -> np.ndarray:
        if name not in self._fresh:
            with self._lock:
                if name not in self._fresh:
                    src = getattr(self, name + "_t")
                    view = self._views.get(name)
                    if view is None:  # allocated once, refreshed in place after each change
                        view = np.empty((src.shape[-1],) + src.shape[:-1], dtype=F32)
                        self._views[name] = view
                    rows = src.reshape(int(np.prod(src.shape[:-1])), src.shape[-1])  # (n * 2, C) or (n, C)
                    flat = view.reshape(src.shape[-1], rows.shape[0])  # (C, n * 2): the same memory
                    np.copyto(flat, rows.T)
                    self._fresh.add(name)
        return self._views[name]

    @property
    def bend(self) -> np.ndarray:
        return self._public("bend")

    @property
    def bend_vel(self) -> np.ndarray:
        return self._public("bend_vel")

    @property
    def twist(self) -> np.ndarray:
        return self._public("twist")

    @property
    def twist_vel(self) -> np.ndarray:
        return self._public("twist_vel")

    def overlaid(self, bend_t: np.ndarray) -> SolverState:
        """A state sharing this one's arrays but with ``bend_t`` as its bend (what is shown
        with the colliders on top of the wind's state; the solver never steps it)."""
        out = SolverState.__new__(SolverState)
        out.bend_t, out.bend_vel_t, out.twist_t = bend_t, self.bend_vel_t, self.twist_t
        out.twist_vel_t, out.bend_eq_t = self.twist_vel_t, self.bend_eq_t
        out._views, out._fresh, out._lock = {}, set(), threading.Lock()
        return out

    def copy(self) -> SolverState:
        out = SolverState(self.n_cells, self.segments)
        out.assign(self)
        return out

    def assign(self, other: SolverState) -> None:
        """Copy ``other``'s values into this state (bitwise)."""
        for name in STATE_ARRAYS:
            np.copyto(getattr(self, name), getattr(other, name))
        self.changed()

    def reset(self) -> None:
        for name in STATE_ARRAYS:
            getattr(self, name).fill(0.0)
        self.changed()

    def equals(self, other: SolverState) -> bool:
        """Bitwise equality of every array."""
        return all(np.array_equal(getattr(self, k).view(np.uint32), getattr(other, k).view(np.uint32))
                   for k in STATE_ARRAYS)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, k).nbytes for k in STATE_ARRAYS)


class _Scratch:
    """Preallocated float32/bool buffers of one worker lane; ``get`` hands out contiguous views.

    Views are cached per (name, shape, dtype): a chunk asks for ~60 buffers and every call costs
    (np.prod on a shape tuple alone was ~5 us). ``pad=True`` pads the rows apart, for the
    buffers of the running sums over joints (``np.add(M[i + 1], F[i], out=M[i])``): numpy treats
    adjacent rows of one buffer as overlapping and goes through a temporary copy, ~5x slower.
    The others stay contiguous (cheaper calls).
    """

    def __init__(self):
        self._bufs: dict[str, np.ndarray] = {}
        self._views: dict[tuple, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype=F32, pad: bool = False) -> np.ndarray:
        key = (name, shape, dtype)
        view = self._views.get(key)
        if view is None:
            padded = shape[:-1] + (shape[-1] + (ROW_PAD if pad else 0),)
            size = math.prod(padded)
            buf = self._bufs.get(name)
            if buf is None or buf.size < size or buf.dtype != dtype:
                buf = np.empty(size, dtype=dtype)
                self._bufs[name] = buf
            view = buf[:size].reshape(padded)[..., :shape[-1]]
            self._views[key] = view
        return view

    def const(self, name: str, value: float, m: int) -> np.ndarray:
        """A (m,) row filled with value once: min/max against a row run on numpy's fast
        array-array loops (against a scalar they are several times slower)."""
        key = ("const", name, m)
        row = self._views.get(key)
        if row is None:
            row = np.full(m, value, dtype=F32)
            self._views[key] = row
        return row


def _clip(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    np.minimum(x, hi, out=x)
    np.maximum(x, lo, out=x)


@dataclass
class _Forcing:
    """Phase 1, eqs 14-20: the wind's loads on a chunk of cells, joint-major (n, m)."""

    w_hat: np.ndarray  # (2, m) horizontal unit wind direction (zero without wind)
    speed: np.ndarray  # (m,) |v| m/s, at least 1e-6
    delta0: np.ndarray | None  # (m,) angle from the rest face normal to the wind line
    force: np.ndarray  # F_j of eq 17 times l_length
    force_above: np.ndarray  # S_i = sum_{j>=i} F_j
    cos_tilt: np.ndarray  # cos |T_j|
    bend_torque: np.ndarray  # M_i of eq 18, N m, along w_hat
    twist_torque: np.ndarray  # M_t,i of eq 20, N m


@dataclass
class _Equilibrium:
    """Phase 2, eqs 21-24: stiffness, equilibria and the gaps to them, joint-major (n, m)."""

    mu: np.ndarray  # mu_i(t) of eqs 22-23
    k_over_i: np.ndarray  # K / I = w^2 of the joint's swing
    twist_eq: np.ndarray  # the equilibrium twist
    gap: np.ndarray  # (n, 2, m) E - theta (the oscillator integrates it in place)
    gap_size: np.ndarray  # |E - theta|
    twist_gap: np.ndarray  # phi_eq - phi
    twist_gap_size: np.ndarray  # |phi_eq - phi|
    swing: np.ndarray  # swing amplitude |dtheta_i| + |dphi_i| of eq 28


@dataclass
class _Split:
    """Phase 3, eq 28: rows [j0, j1) hold every oscillating joint of the chunk; ``swinging``
    ((j1 - j0, m), 1 where the joint oscillates) and ``steady`` (1 - swinging), or None."""

    j0: int
    j1: int
    swinging: np.ndarray | None
    steady: np.ndarray | None


@dataclass
class _Rows:
    """The rows of joints and cells one oscillator pass works on (views into the state and the
    equilibrium): angles and rates, the gaps y = theta_eq - theta, the smooth factors x and the
    masks of the joints that swing (1/0) or not (0/1)."""

    bend: np.ndarray
    vel: np.ndarray
    twist: np.ndarray
    twist_vel: np.ndarray
    eq: np.ndarray
    gap: np.ndarray
    twist_gap: np.ndarray
    twist_eq: np.ndarray
    x: np.ndarray
    xt: np.ndarray
    swinging: np.ndarray
    steady: np.ndarray


def _limits(S: _Scratch, m: int, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """(-limit, limit) rows of m cells, kept in the scratch space."""
    return S.const(f"lo{limit}", -limit, m), S.const(f"hi{limit}", limit, m)


def base_oscillator(layout, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """``BladeSolver(layout, params).recovery_oscillator()``, the same bits, without a solver:
    (K/M, C/M) of each cell's base joint at rest, (C,) float64 each (eqs 29-31)."""
    b, n = params.blade, int(layout.segments)
    seg = np.asarray(layout.cell_length, dtype=np.float64) / n
    mu = np.ascontiguousarray(blade.joint_stiffness(layout.cell_root_stiffness, seg, n, b.stiffness_offset)[:, 0])
    inv_inertia = (1.0 / (b.density * (n * seg) ** 3)).astype(F32)
    omega2 = np.asarray(mu, np.float64) * inv_inertia
    return omega2, float(b.damping_mass) + float(b.damping_stiffness) * omega2


def _balanced_chunks(C: int, chunk_cells: int, threads: int) -> list[tuple[int, int]]:
    """Cells [0, C) cut into equal chunks of at most ``chunk_cells``, as few as can be (fewer,
    longer numpy calls beat cache locality here: each costs ~1-2 us of Python and setup), and a
    multiple of ``threads`` of them so that every lane steps as many cells: 136,704 cells over two
    lanes are 4 x 34,176, not 65,536 + 65,536 + 5,632 (one lane doing 96 % of the work)."""
    if C <= 0:
        return []
    count = -(-C // chunk_cells)
    count = min(C, -(-count // threads) * threads)
    edges = [i * C // count for i in range(count + 1)]  # sizes differ by at most one cell
    return list(zip(edges[:-1], edges[1:]))


class BladeSolver:
    """Bending/twisting of every cell's representative blade (paper V.A). See the module doc."""

    def __init__(self, layout, params: Params, chunk_cells: int = 65536, threads: int = 2):
        b = params.blade
        n = int(layout.segments)
        C = int(layout.n_cells)
        self.layout = layout
        self.params = params
        self.n, self.n_cells = n, C
        self.chunk_cells = max(1, int(chunk_cells))
        self.threads = max(1, int(threads)) if C >= ONE_LANE_CELLS else 1
        # k of eq 23 per joint: stiffness and the joint angles of a given curvature scale with
        # n / REFERENCE_SEGMENTS and its inverse (blade.joint_stiffness), so k by its square and
        # the angle where stiffening stops by its inverse: the bent shape does not depend on n.
        per_joint = n / blade.REFERENCE_SEGMENTS
        self.k = float(b.nonlinear_stiffness) * per_joint * per_joint
        self.stiffen_limit = STIFFEN_LIMIT / per_joint
        self.gamma = float(b.response_torque)  # gamma of eq 26
        self.twist_ratio = float(b.twist_stiffness)  # twist stiffness = ratio * mu
        self.alpha = float(b.damping_mass)  # alpha of eq 31
        self.beta = float(b.damping_stiffness)  # beta of eq 31
        self.air_damping = float(b.air_damping)  # share of the drag's damping 2 Q / v (beyond the paper)
        self.boundary_k = float(b.boundary_k)  # k of eq 28
        self.boundary_lambda = float(b.boundary_lambda)  # lambda of eq 28
        self.min_substeps = int(params.simulation.sub_steps)

        seg = np.asarray(layout.cell_length, dtype=np.float64) / n  # l_length
        self._seg = seg.astype(F32)
        # mu_i^base of eqs 1 and 5, joint-major (n, C)
        self._mu_base = np.ascontiguousarray(
            blade.joint_stiffness(layout.cell_root_stiffness, seg, n, b.stiffness_offset).T)
        # Segment width: the strip tapers linearly from the root width to tip_width * width (the
        # width of eq 16 is taken at the segment's middle).
        width = np.asarray(layout.cell_width, dtype=np.float64)[None, :] * \
            blade.segment_widths(b.tip_width, n)[:, None]
        # rho_wind * l_length * l_width (eqs 16-17) times the lever unit l_length: eq 18's
        # torques then come out in N m without a pass of their own (_forcing)
        self._area_seg = (RHO_AIR * seg[None, :] ** 2 * width).astype(F32)
        # Moment of inertia about joint i of the part above it, used for M_grass of eqs 29-32.
        # The paper's M_grass is a mass, but K = mu_i is a torque per radian, so the consistent
        # quantity is a moment of inertia. We lump the mass of the (n - i) segments above joint i,
        # (n - i) rho_grass l_length, at the lever (n - i) l_length, exactly as eqs 3-4 place the
        # weight of that part: I_i = rho_grass ((n - i) l_length)^3. (A uniform rod would give a
        # third of this; the lumped value also stands for the drag of the joints above, which
        # must follow joint i's motion, and gives the 1-3 Hz sway of real blades.)
        j = np.arange(n, dtype=np.float64)[:, None]
        above = (n - j) * seg[None, :]
        inertia = b.density * above ** 3
        self._inv_inertia = (1.0 / inertia).astype(F32)
        facing = np.asarray(layout.cell_facing, dtype=np.float64)
        self._face = np.stack([np.cos(facing), np.sin(facing)]).astype(F32)  # rest face normal
        rest = np.asarray(layout.cell_rest_tilt, dtype=np.float64).T  # (n, C)
        self._rest = np.stack([rest * np.cos(facing), rest * np.sin(facing)], axis=1).astype(F32)  # (n, 2, C)
        self._level = np.arange(1, n + 1, dtype=F32)[:, None]  # 1-based joint index of eq 28

        self.state = SolverState(C, n)
        # n_boundary of eq 28 of the last step, per cell (joints with 1-based index above it
        # oscillate); n everywhere at rest.
        self.n_boundary = np.full(C, n, dtype=F32)
        self._chunks = _balanced_chunks(C, self.chunk_cells, self.threads)
        lanes = min(self.threads, len(self._chunks))
        self._lanes = [self._chunks[i::lanes] for i in range(lanes)]
        self._scratch = [_Scratch() for _ in range(lanes)]
        self._allowed_cache: dict[tuple[float, float], np.ndarray] = {}
        self._allowed_rows: dict[int, int] = {}  # chunk start -> j1 for the cached allowed
        self._quasi_cache: tuple[float | None, np.ndarray | None] = (None, None)
        self._quasi_static = np.zeros((0, 0), F32)  # (each step's, for its dt)
        # Stiffest joint: eq 22-23 with the nonlinear part at its bound (the bend is clamped).
        k_max = self._mu_base + F32(self.k * self.stiffen_limit)
        ratio = max(1.0, self.twist_ratio)  # twist uses ratio * K with the same inertia
        self._omega2 = (k_max.astype(np.float64) * self._inv_inertia * ratio)  # K/I, (n, C)
        self._damp = self.alpha + self.beta * self._omega2  # C/I of eq 31

    # ---------------------------------------------------------------------------- public API

    def reset(self) -> None:
        self.state.reset()
        self.n_boundary.fill(self.n)

    def close(self) -> None:
        """Nothing to release: the lanes run on the engine's shared pool (workers.py)."""

    def recovery_oscillator(self) -> tuple[np.ndarray, np.ndarray]:
        """(K/M, C/M) of each cell's base joint at rest, (C,) float64 each (eqs 29-31): how a
        blade released from a bend sways back (interaction.py's trampled grass)."""
        omega2 = np.asarray(self._mu_base[0], np.float64) * self._inv_inertia[0]
        return omega2, self.alpha + self.beta * omega2

    def stable_substeps(self, frame_dt: float) -> int:
        """Sub-steps per frame that keep eq 32 stable (>= simulation.sub_steps).

        Symplectic Euler on theta'' + c theta' + w^2 theta = 0 is stable for h c < 2 and
        h^2 w^2 + 2 h c < 4. We ask for half of each bound (h c <= 1, h^2 w^2 + 2 h c <= 2) for
        the fastest joint that may oscillate at this frame rate. A joint
        whose natural period is shorter than FRAMES_PER_SWAY frames cannot show a sway at this rate
        (it would flicker or alias); such a joint (the short tip segment,
        typically) follows the smooth update of eqs 25-27 instead of eq 32, which is
        its quasi-static limit, and does not raise the sub-step count.
        """
        frame_dt = float(frame_dt)
        if not (frame_dt > 0.0 and math.isfinite(frame_dt)):
            raise ValueError(f"frame_dt must be a positive number of seconds, got {frame_dt!r}")
        # The bound uses the fastest joint the rate can show (w^2 = the visible limit) and its
        # damping, not the cells at hand: the count is a function of the parameters alone, the
        # same for the whole field and for any window of it.
        w2 = self._visible_omega2(frame_dt)
        c = self.alpha + self.beta * w2
        h = (-c + math.sqrt(c * c + 2.0 * w2)) / w2
        if c > 0:
            h = min(h, 1.0 / c)
        need = max(1, math.ceil(frame_dt / h - 1e-9))
        return max(self.min_substeps, min(need, AUTO_MAX_SUBSTEPS))

    def equilibrium_bend(self, wind: np.ndarray) -> np.ndarray:
        """Plain Hooke's-law equilibrium |M_i^bend| / mu_i^base (eqs 6/21, no smoothing), (n_cells, n).

        The torques are those of the current shape (eqs 16-18), as in ``step``.
        """
        wind = self._check_wind(wind)
        scratch = _Scratch()
        out = np.empty((self.n, self.n_cells), dtype=F32)
        for a, b in self._chunks:
            forcing = self._forcing(a, b, wind, scratch, twist=False)
            np.divide(forcing.bend_torque, self._mu_base[:, a:b], out=out[:, a:b])
        return np.ascontiguousarray(out.T)

    def step(self, wind: np.ndarray, dt: float, substeps: int = 1) -> None:
        """Advance the state by ``dt`` seconds under ``wind`` ((n_cells, 2) m/s).

        The forcing (eqs 16-24) and eq 28 are evaluated once; the smooth update (eqs 25-27) is
        exact for any dt; the oscillating joints take ``substeps`` sub-steps of eq 32. The
        Simulation calls ``step(wind, frame_dt, stable_substeps(frame_dt))`` once per frame.
        """
        wind = self._check_wind(wind)
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        substeps = max(1, int(substeps))
        h = dt / substeps
        allowed = self._oscillator_allowed(dt, h)
        kept_dt, quasi = self._quasi_cache
        if quasi is None or kept_dt != dt:
            fast = self._omega2 > self._visible_omega2(dt)
            quasi = np.where(fast, F32(QUASI_RATE), F32(0.0)).astype(F32)
            self._quasi_cache = (dt, quasi)
        self._quasi_static = quasi
        def run(lane: int) -> None:
            for a, b in self._lanes[lane]:
                self._step_chunk(a, b, wind, dt, substeps, allowed, self._scratch[lane])

        workers.run_lanes(run, len(self._lanes))
        self.state.changed()

    # ---------------------------------------------------------------------------- internals

    def _check_wind(self, wind: np.ndarray) -> np.ndarray:
        wind = np.asarray(wind, dtype=F32)
        if wind.shape != (self.n_cells, 2):
            raise ValueError(f"wind must have shape ({self.n_cells}, 2) (one 2-D vector per cell), "
                             f"got {wind.shape}")
        return wind

    @staticmethod
    def _visible_omega2(frame_dt: float) -> float:
        """w^2 of the fastest sway a frame rate shows as a sway: FRAMES_PER_SWAY frames per period."""
        return (2.0 * math.pi / (FRAMES_PER_SWAY * frame_dt)) ** 2

    def _oscillator_allowed(self, dt: float, h: float) -> np.ndarray:
        """(n, C) bool: joints that use eq 32 in a step of dt with sub-step h: visible at this
        rate (w <= pi / dt) and stable (h c <= 1, h^2 w^2 + 2 h c <= 2); see stable_substeps."""
        key = (dt, h)
        allowed = self._allowed_cache.get(key)
        if allowed is None:
            hc = h * self._damp
            allowed = ((hc <= 1.0) & (h * h * self._omega2 + 2.0 * hc <= 2.0)
                       & (self._omega2 <= self._visible_omega2(dt)))
            self._allowed_cache = {key: allowed}
            self._allowed_rows = {}
        return allowed

    def _oscillating_rows(self, allowed: np.ndarray, a: int, b: int) -> int:
        """j1: joints j >= j1 of cells [a, b) never use eq 32 with this ``allowed`` (typically
        the stiff tip joint); the oscillator's passes skip them."""
        j1 = self._allowed_rows.get(a)
        if j1 is None:
            rows = np.flatnonzero(allowed[:, a:b].any(axis=1))
            j1 = int(rows[-1]) + 1 if rows.size else 0
            self._allowed_rows[a] = j1
        return j1

    # ------------------------------------------------------------------ phase 1: eqs 14-20

    def _forcing(self, a: int, b: int, wind: np.ndarray, S: _Scratch, twist: bool = True) -> _Forcing:
        """Wind loads on cells [a, b) for the shape of the equilibrium estimate E (eqs 14-20)."""
        v2, speed, w_hat, delta0 = self._wind_in_cells(a, b, wind, S, twist)
        force, twist_torque, cos_tilt = self._segment_loads(a, b, v2, w_hat, S)
        force_above, bend_torque = self._joint_torques(force, cos_tilt, twist_torque, S)
        return _Forcing(w_hat, speed, delta0, force, force_above, cos_tilt, bend_torque, twist_torque)

    def _wind_in_cells(self, a: int, b: int, wind: np.ndarray, S: _Scratch, twist: bool):
        """(v^2, |v|, the horizontal unit wind direction, delta0) of cells [a, b); delta0 (with
        ``twist``): the angle from the rest face normal (a line: both sides face) to the wind
        line, in [-pi/2, pi/2)."""
        m = b - a
        W = S.get("wind", (2, m))
        np.copyto(W, wind[a:b].T)
        v2 = S.get("wind_speed2", (m,))
        wy2 = S.get("wind_y2", (m,))
        np.multiply(W[0], W[0], out=v2)
        np.multiply(W[1], W[1], out=wy2)
        v2 += wy2
        speed = S.get("wind_speed", (m,))
        np.sqrt(v2, out=speed)
        np.maximum(speed, S.const("tiny_speed", 1e-6, m), out=speed)
        w_hat = S.get("wind_direction", (2, m))  # horizontal unit wind direction (zero without wind)
        np.divide(W, speed, out=w_hat)
        delta0 = None
        if twist:
            # arctan2(cross * dot, dot^2) of the rest face normal and the wind
            delta0 = S.get("face_to_wind", (m,))
            dot, cross = S.get("face_dot_wind", (m,)), S.get("face_cross_wind", (m,))
            face = self._face[:, a:b]
            np.multiply(face[0], W[0], out=dot)
            np.multiply(face[1], W[1], out=wy2)
            dot += wy2
            np.multiply(face[0], W[1], out=cross)
            np.multiply(face[1], W[0], out=wy2)
            cross -= wy2
            cross *= dot
            dot *= dot
            np.arctan2(cross, dot, out=delta0)
        return v2, speed, w_hat, delta0

    def _segment_loads(self, a: int, b: int, v2, w_hat, S: _Scratch):
        """(F^bend of eq 17, the twist load of eqs 19-20, cos |T_j|) of every segment of cells
        [a, b) in the shape of the equilibrium estimate E, each (n, m), times l_length."""
        n, m = self.n, b - a
        eq_bend = self.state.bend_eq_t[:, :, a:b]  # the loads act on E, not on the swinging blade
        # v^2 rho_wind l_length l_width, times l_length: the lever unit of eq 18 (see below)
        area = S.get("wind_area", (n, m))
        np.multiply(self._area_seg[:, a:b], v2, out=area)

        # Absolute tilt vectors T_j = rest_j + sum_{k<=j} E_k of every segment (n, 2, m); the
        # running sum is the only loop over joints, the rest runs on all joints at once.
        T = S.get("tilt_vector", (n, 2, m), pad=True)
        np.copyto(T[0], eq_bend[0])
        for j in range(1, n):
            np.add(T[j - 1], eq_bend[j], out=T[j])
        T += self._rest[:, :, a:b]
        products = S.get("tilt_vector_products", (n, 2, m))
        tilt = S.get("tilt", (n, m))
        sin_tilt = S.get("sin_tilt", (n, m))
        cos_phi = S.get("cos_phi", (n, m))
        force = S.get("force", (n, m))  # F_i^bend of eq 17 (times l_length)
        cos_tilt = S.get("cos_tilt", (n, m))  # cos |T_j|: vertical extent of segment j / l_length

        np.multiply(T, T, out=products)
        np.add(products[:, 0], products[:, 1], out=tilt)
        np.sqrt(tilt, out=tilt)  # |T_j|
        np.sin(tilt, out=sin_tilt)
        np.cos(tilt, out=cos_tilt)
        # eq 16: cos(phi) = a_j . w with the axis a_j = (sin|T| T/|T|, cos|T|), w horizontal
        np.multiply(T, w_hat[None, :, :], out=products)
        np.add(products[:, 0], products[:, 1], out=cos_phi)
        np.maximum(tilt, S.const("eps", EPS, m), out=tilt)
        np.divide(cos_phi, tilt, out=cos_phi)
        cos_phi *= sin_tilt
        sin_phi = S.get("sin_phi", (n, m))
        np.multiply(cos_phi, cos_phi, out=sin_phi)
        np.subtract(F32(1.0), sin_phi, out=sin_phi)
        np.maximum(sin_phi, S.const("zero", 0.0, m), out=sin_phi)
        np.sqrt(sin_phi, out=sin_phi)
        # eq 17: F = v^2 rho l_length l_width sin(phi); a segment bent along the wind shows it
        # less area (sin phi -> 0), which bounds the bend physically (reconfiguration).
        np.multiply(area, sin_phi, out=force)
        # eqs 19-20: F_twist = v^2 rho l l_w cos(phi) on the lever l sin(theta + theta_base),
        # theta + theta_base = the segment's absolute tilt |T_j| (its size; the direction is set
        # in _equilibrium). |cos(phi) sin|T||: a lever is a distance.
        twist_torque = S.get("twist_torque", (n, m), pad=True)
        np.multiply(cos_phi, sin_tilt, out=twist_torque)  # per segment, summed over joints below
        np.abs(twist_torque, out=twist_torque)
        twist_torque *= area
        return force, twist_torque, cos_tilt

    def _joint_torques(self, force, cos_tilt, twist_torque, S: _Scratch):
        """(S_i = sum_{j>=i} F_j, M_i of eq 18) of every joint; sums the segments' twist loads in
        place into M_t,i of eq 20 (twisting joint i turns every segment above it)."""
        n, m = force.shape
        # eq 18 with the statics of eqs 3-4: joint i carries the wind load of every segment
        # above it; M_i = sum_{j>=i} F_j * (vertical lever from joint i to segment j's centre),
        # directed along w. Recursively, with z_i = l cos|T_i| and S_{i+1} = sum_{j>i} F_j:
        # M_i = M_{i+1} + z_i (S_{i+1} + F_i / 2). The factor l_length of z_i is already in F
        # (area_seg), so the running sums below come out in N m.
        last = n - 1
        force_above = S.get("force_above", (n, m), pad=True)  # S_i = sum_{j>=i} F_j
        np.copyto(force_above[last], force[last])
        for i in range(last - 1, -1, -1):
            np.add(force_above[i + 1], force[i], out=force_above[i])
        lever_load = S.get("lever_load", (n, m))  # z_i (S_{i+1} + F_i / 2)
        np.multiply(force, F32(0.5), out=lever_load)
        lever_load[:last] += force_above[1:]
        lever_load *= cos_tilt
        bend_torque = S.get("bend_torque", (n, m), pad=True)
        np.copyto(bend_torque[last], lever_load[last])
        for i in range(last - 1, -1, -1):
            np.add(bend_torque[i + 1], lever_load[i], out=bend_torque[i])
        # twisting joint i turns every segment above: M_t,i = sum_{j>=i} F_twist,j
        for i in range(last - 1, -1, -1):
            np.add(twist_torque[i + 1], twist_torque[i], out=twist_torque[i])
        return force_above, bend_torque

    # ------------------------------------------------------------------ phase 2: eqs 21-27

    def _equilibrium(self, a: int, b: int, forcing: _Forcing, dt: float, S: _Scratch) -> _Equilibrium:
        """mu_i(t) (eqs 22-23), the equilibrium bend and twist (eqs 21, 24), E relaxed towards
        the reconfigured statics, and the gaps E - theta, phi_eq - phi."""
        n, m = self.n, b - a
        products = S.get("bend_products", (n, 2, m))
        mu = self._stiffness(a, b, products, S)
        # eq 21/24: equilibrium bend = M_i^bend / mu_i(t), along the wind (vector e w_hat)
        e = S.get("equilibrium_bend", (n, m))
        np.divide(forcing.bend_torque, mu, out=e)
        _clip(e, S.const("bend_lo", -BEND_LIMIT, m), S.const("bend_hi", BEND_LIMIT, m))
        twist_eq = self._equilibrium_twist(mu, forcing, S)
        self._relax_estimate(a, b, e, forcing, dt, products, S)
        return self._gaps(a, b, mu, twist_eq, products, S)

    def _stiffness(self, a: int, b: int, products, S: _Scratch) -> np.ndarray:
        """eqs 22-23: mu_i(t) = mu_i^base + k |theta_i(t - dt)| (bend of the previous step)."""
        n, m = self.n, b - a
        bend = self.state.bend_t[:, :, a:b]
        mu = S.get("stiffness", (n, m))
        np.multiply(bend, bend, out=products)
        np.add(products[:, 0], products[:, 1], out=mu)
        np.sqrt(mu, out=mu)
        np.minimum(mu, S.const("stiffen", self.stiffen_limit, m), out=mu)
        mu *= F32(self.k)
        mu += self._mu_base[:, a:b]
        return mu

    def _equilibrium_twist(self, mu, forcing: _Forcing, S: _Scratch) -> np.ndarray:
        """The twist of each joint at equilibrium (eq 24 for the twist).

        The same process as the bend with stiffness K_t = twist_stiffness * mu_i(t). The paper
        gives the twisting torque's size (eq 20) but not its direction: it turns the face
        towards broadside to the wind and vanishes there, like M_t sin(2 (delta - phi)) with
        delta the angle from the face normal to the wind. Linearised, joint i's equilibrium
        turns the face by the fraction s_i = 2 M_t / (K_t + 2 M_t) = M_t / (K_t / 2 + M_t) of
        the angle still left by the joints below: phi_eq_i = s_i (delta0 - sum_{k<i} phi_eq_k).
        Self-limiting (the face never turns past broadside) and independent of the current
        twist, so it needs no fixed-point iteration (a twist-dependent torque on cumulative
        joints flutters)."""
        n, m = mu.shape
        twist_eq = S.get("equilibrium_twist", (n, m))
        np.multiply(mu, F32(0.5 * self.twist_ratio), out=twist_eq)  # K_t / 2
        twist_eq += forcing.twist_torque  # > 0: mu >= mu_base > 0, M_t >= 0
        np.divide(forcing.twist_torque, twist_eq, out=twist_eq)  # s_i
        left = S.get("twist_left", (m,))
        assert forcing.delta0 is not None  # (the equilibrium's forcing is computed with the twist)
        np.copyto(left, forcing.delta0)
        for i in range(n):
            twist_eq[i] *= left
            left -= twist_eq[i]
        _clip(twist_eq, S.const("twist_lo", -TWIST_LIMIT, m), S.const("twist_hi", TWIST_LIMIT, m))
        return twist_eq

    def _relax_estimate(self, a: int, b: int, e, forcing: _Forcing, dt: float, products, S: _Scratch) -> None:
        """Move the equilibrium estimate E towards the statics e w_hat (in place).

        Reconfiguration makes the equilibrium depend on the shape it is computed on (eqs 16-18:
        a bent segment catches less wind, on a shorter lever). Evaluated on the swinging blade
        of the previous frame, that feedback flutters (the target jumps frame to frame). As
        blade.rest_angles does for gravity, we solve the statics by under-relaxed fixed-point
        iteration, one iteration per step, on a persistent estimate E whose shape the loads
        act on: E += (eq(E) - E) r. The iteration is stable while d(eq)/dE > 1 - 2 / r, and
        that slope is about -RELAX_GAIN sum_j |eq_j| (the load, hence its loss by
        reconfiguration, grows with the bend it causes; the joints couple through the
        cumulative tilt, so the whole blade's bend counts), so the cell's
        r = 1 / (1 + RELAX_GAIN sum_j |eq_j|) per reference frame (scaled by dt / dt_ref for
        shorter steps): a full step when the wind drops (eq = 0, the blade is released at once
        and swings back), short steps in a storm. Written E = E (1 - r) + (e r) w_hat."""
        n, m = self.n, b - a
        E = self.state.bend_eq_t[:, :, a:b]
        relax = S.get("relax", (m,))
        e_size = S.get("equilibrium_bend_size", (n, m))
        np.abs(e, out=e_size)
        np.add.reduce(e_size, axis=0, out=relax)
        relax *= F32(RELAX_GAIN)
        relax += F32(1.0)
        np.divide(F32(min(1.0, dt / REFERENCE_DT)), relax, out=relax)
        e *= relax
        np.multiply(e[:, None, :], forcing.w_hat[None, :, :], out=products)
        np.subtract(F32(1.0), relax, out=relax)
        E *= relax
        E += products

    def _gaps(self, a: int, b: int, mu, twist_eq, products, S: _Scratch) -> _Equilibrium:
        """The gaps to the equilibrium position E: the angles "relative to the equilibrium
        position" of eq 28, and what the smooth update (eq 26) and the oscillator close."""
        n, m = self.n, b - a
        st = self.state
        bend, vel = st.bend_t[:, :, a:b], st.bend_vel_t[:, :, a:b]
        twist, E = st.twist_t[:, a:b], st.bend_eq_t[:, :, a:b]
        gap = S.get("gap", (n, 2, m))
        np.subtract(E, bend, out=gap)
        gap_size = S.get("gap_size", (n, m))
        np.multiply(gap, gap, out=products)
        np.add(products[:, 0], products[:, 1], out=gap_size)  # squared until the swing is known
        k_over_i = S.get("stiffness_per_inertia", (n, m))  # K / I = w^2
        np.multiply(mu, self._inv_inertia[:, a:b], out=k_over_i)
        # A joint swinging through its equilibrium is not at equilibrium, so eq 28 takes its swing
        # amplitude, sqrt(dtheta^2 + (theta'/w)^2) (equal to |dtheta| for a joint at rest);
        # otherwise it would stop a swing at every crossing. (The twist counts with |dphi|.)
        swing = S.get("swing", (n, m))
        np.multiply(vel, vel, out=products)
        np.add(products[:, 0], products[:, 1], out=swing)
        swing /= k_over_i
        swing += gap_size
        np.sqrt(swing, out=swing)
        np.sqrt(gap_size, out=gap_size)
        twist_gap = S.get("twist_gap", (n, m))
        np.subtract(twist_eq, twist, out=twist_gap)
        twist_gap_size = S.get("twist_gap_size", (n, m))
        np.abs(twist_gap, out=twist_gap_size)
        swing += twist_gap_size  # |dtheta_i| + |dphi_i| of eq 28
        return _Equilibrium(mu, k_over_i, twist_eq, gap, gap_size, twist_gap, twist_gap_size, swing)

    # ------------------------------------------------------------------ phase 3: eq 28

    def _boundary(self, a: int, b: int, eqm: _Equilibrium, allowed: np.ndarray, S: _Scratch) -> _Split:
        """n_boundary (eq 28) of every cell, and which joints oscillate: those above it where
        eq 32 is allowed. They are the top ones of each cell, so rows [j0, j1) hold them all."""
        n, m = self.n, b - a
        # n_boundary = n exp(-((1/2n) sum_i (|dtheta_i| + |dphi_i|) - k) lambda), in [0, n]
        nb = self.n_boundary[a:b]
        np.add.reduce(eqm.swing, axis=0, out=nb)
        nb *= F32(0.5 / n)
        nb -= F32(self.boundary_k)
        nb *= F32(-self.boundary_lambda)
        np.minimum(nb, S.const("nb_exp_max", math.log(n) + 1.0, m), out=nb)  # n_boundary > n anyway
        np.exp(nb, out=nb)
        nb *= F32(n)
        np.minimum(nb, S.const("n", n, m), out=nb)
        j1 = self._oscillating_rows(allowed, a, b)
        if j1 == 0:
            return _Split(0, 0, None, None)
        oscillates = S.get("oscillates", (j1, m), dtype=np.bool_)
        np.greater(self._level[:j1], nb, out=oscillates)
        np.logical_and(oscillates, allowed[:j1, a:b], out=oscillates)
        rows = oscillates.any(axis=1)
        if not rows.any():
            return _Split(j1, j1, None, None)
        j0 = int(np.argmax(rows))
        swinging = S.get("swinging", (j1 - j0, m))  # 1 where the joint oscillates
        np.copyto(swinging, oscillates[j0:j1])
        steady = S.get("steady", (j1 - j0, m))
        np.subtract(F32(1.0), swinging, out=steady)
        return _Split(j0, j1, swinging, steady)

    # ------------------------------------------------------------------ phase 2b: eqs 25-27

    def _smooth_fractions(self, a: int, b: int, eqm: _Equilibrium, split: _Split, dt: float, S: _Scratch):
        """(x, xt) = -f of the smooth three-step update of the bend and the twist, (n, m).

        Eq 26 makes the fraction per frame M/gamma, which overshoots once M > gamma; the sound
        reading is a rate: d(theta)/dt = (theta_eq - theta) * M / (gamma dt_ref), integrated
        exactly over dt: f = 1 - exp(-(M / gamma) dt / dt_ref), stable and frame-rate
        independent. M is the unbalanced torque |M_bend - mu theta| = mu |theta_eq - theta|: it
        equals M_bend when starting from rest and stays non-zero when the wind stops, so the
        lower part recovers too. As the gap closes M -> 0 and the return would crawl
        (hyperbolically: a blade that looks frozen a few degrees off); a linear spring returns at
        a rate independent of the gap, so below SMOOTH_MIN_ANGLE the rate is held at its value
        there: M = mu max(|theta_eq - theta|, SMOOTH_MIN_ANGLE). Joints too stiff to show a sway
        at this frame rate (see stable_substeps) are in their quasi-static limit: they follow
        theta_eq within the step (f = 1: the rate minus QUASI_RATE makes exp underflow to 0).
        The oscillating joints take no smooth step (x = 0)."""
        n, m = self.n, b - a
        floor = S.const("smooth_min", SMOOTH_MIN_ANGLE, m)
        rate = S.get("smooth_rate", (n, m))  # -mu dt / (gamma dt_ref): x = -log(1 - f) / gap
        np.multiply(eqm.mu, F32(-dt / (self.gamma * REFERENCE_DT)), out=rate)
        rate -= self._quasi_static[:, a:b]
        if split.steady is not None:
            rate[split.j0:split.j1] *= split.steady
        x = S.get("smooth_fraction", (n, m))
        np.maximum(eqm.gap_size, floor, out=x)
        x *= rate
        np.expm1(x, out=x)  # -f
        xt = S.get("smooth_fraction_twist", (n, m))  # with K_t = twist_stiffness * mu
        np.maximum(eqm.twist_gap_size, floor, out=xt)
        xt *= rate
        xt *= F32(self.twist_ratio)
        np.expm1(xt, out=xt)
        return x, xt

    def _smooth_update(self, a: int, b: int, rows: slice, eqm: _Equilibrium, x, xt, dt: float, substeps: int,
                       S: _Scratch) -> None:
        """Joints ``rows`` (none oscillating): theta -= (E - theta) x, and its rate
        d theta / dt = -(E - theta) x / dt (eq 27). It stays within bounds by itself: it moves
        between two bounded angles. (The gap buffers hold the step afterwards.)

        With one sub-step it is the arithmetic of ``_step_once`` for a joint that does not swing
        (rate (E - theta) (-x / dt), step rate dt, clipped), so a joint gets the same bits whether
        its chunk's other cells make its row oscillate or not: a cell's bits never depend on the
        cells stepped with it (``far_sway.py`` steps some alone)."""
        st, m = self.state, b - a
        if substeps == 1:
            rate = S.get("smooth_rate", (rows.stop - rows.start, m))
            np.multiply(x[rows], F32(-1.0 / dt), out=rate)
            vel = st.bend_vel_t[rows, :, a:b]
            np.multiply(eqm.gap[rows], rate[:, None, :], out=vel)
            step = eqm.gap[rows]
            np.multiply(vel, F32(dt), out=step)
            st.bend_t[rows, :, a:b] += step
            _clip(st.bend_t[rows, :, a:b], *_limits(S, m, BEND_LIMIT))
            np.multiply(xt[rows], F32(-1.0 / dt), out=rate)
            twist_vel = st.twist_vel_t[rows, a:b]
            np.multiply(eqm.twist_gap[rows], rate, out=twist_vel)
            twist_step = eqm.twist_gap[rows]
            np.multiply(twist_vel, F32(dt), out=twist_step)
            st.twist_t[rows, a:b] += twist_step
            _clip(st.twist_t[rows, a:b], *_limits(S, m, TWIST_LIMIT))
            return
        inv_dt = F32(-1.0 / dt)
        step = eqm.gap[rows]
        step *= x[rows, None, :]
        st.bend_t[rows, :, a:b] -= step
        np.multiply(step, inv_dt, out=st.bend_vel_t[rows, :, a:b])
        twist_step = eqm.twist_gap[rows]
        twist_step *= xt[rows]
        st.twist_t[rows, a:b] -= twist_step
        np.multiply(twist_step, inv_dt, out=st.twist_vel_t[rows, a:b])

    def _step_chunk(self, a: int, b: int, wind: np.ndarray, dt: float, substeps: int,
                    allowed: np.ndarray, S: _Scratch) -> None:
        """One step of cells [a, b): forcing, equilibrium, boundary, smooth update, oscillator."""
        forcing = self._forcing(a, b, wind, S)
        eqm = self._equilibrium(a, b, forcing, dt, S)
        split = self._boundary(a, b, eqm, allowed, S)
        x, xt = self._smooth_fractions(a, b, eqm, split, dt, S)
        for rows in (slice(0, split.j0), slice(split.j1, self.n)):
            if rows.start < rows.stop:
                self._smooth_update(a, b, rows, eqm, x, xt, dt, substeps, S)
        if split.swinging is not None:
            self._oscillate(a, b, forcing, eqm, split, x, xt, dt, substeps, S)

    # ------------------------------------------------------------------ phase 4: eqs 29-32

    def _aero_q(self, forcing: _Forcing, j0: int, S: _Scratch) -> np.ndarray:
        """Q_i = sum_{j>=i} F_j h_ij^2 for joints i >= j0 (rows below j0 are not written), in
        N m^2 / l_length: the aerodynamic damping of the oscillating joints.

        Q_i = Q_{i+1} + z_i (2 M_{i+1} + z_i (S_{i+1} + F_i / 4)), with F, S, M of the forcing
        (one factor l_length already in F), so a last factor l_length is applied by the caller.
        """
        F, Fs, CT, Mb = forcing.force, forcing.force_above, forcing.cos_tilt, forcing.bend_torque
        n, m = self.n, F.shape[1]
        last = n - 1
        Q = S.get("aero_q", (n, m), pad=True)
        rows = slice(j0, n)
        np.multiply(F[rows], F32(0.25), out=Q[rows])
        Q[j0:last] += Fs[j0 + 1:]
        Q[rows] *= CT[rows]
        Q[j0:last] += Mb[j0 + 1:]
        Q[j0:last] += Mb[j0 + 1:]
        Q[rows] *= CT[rows]
        for i in range(last - 1, j0 - 1, -1):
            Q[i] += Q[i + 1]
        return Q

    def _oscillate(self, a: int, b: int, forcing: _Forcing, eqm: _Equilibrium, split: _Split,
                   x, xt, dt: float, substeps: int, S: _Scratch) -> None:
        """Rows [j0, j1) of cells [a, b): eqs 29-32 for the joints above n_boundary, the smooth
        update (x, xt) for the others of those rows.

        I theta'' + C theta' + K (theta - theta_eq) = 0 with K = mu_i(t), C = alpha I + beta K
        (eq 31), theta_eq = E. With the wind gone E -> 0 and this is eq 29. theta_eq is held for
        the frame, so we integrate y = theta_eq - theta (the gap, in place). Eq 32 (symplectic
        Euler): acceleration, then velocity v += h a, then angle y -= h v; here v = p v + q y
        (``_oscillator_coefficients``). With one step a frame the smooth update is that same step
        (``_step_once``); with several the two are blended (``_substeps``).
        """
        j0, j1 = split.j0, split.j1
        assert split.swinging is not None and split.steady is not None  # (called when some joints swing)
        st, js = self.state, slice(j0, j1)
        rows = _Rows(bend=st.bend_t[js, :, a:b], vel=st.bend_vel_t[js, :, a:b], twist=st.twist_t[js, a:b],
                     twist_vel=st.twist_vel_t[js, a:b], eq=st.bend_eq_t[js, :, a:b], gap=eqm.gap[js],
                     twist_gap=eqm.twist_gap[js], twist_eq=eqm.twist_eq[js], x=x[js], xt=xt[js],
                     swinging=split.swinging, steady=split.steady)
        h = dt / substeps
        coefficients = self._oscillator_coefficients(a, b, forcing, eqm.k_over_i[js], split, h, S)
        if substeps == 1:
            self._step_once(rows, coefficients, h, S)
        else:
            self._substeps(rows, coefficients, h, dt, substeps, S)

    def _oscillator_coefficients(self, a: int, b: int, forcing: _Forcing, kI, split: _Split, h: float,
                                 S: _Scratch) -> tuple:
        """(q, p, q_twist, p_twist) of eq 32's step v <- p v + q y, y <- y - h v for the joints
        that swing (0 for the others): q = h K/I, p = 1 - h C/I with C = alpha I + beta K (eq 31).

        Bend, aerodynamic damping: eq 29 is written for the wind gone; in wind, eq 17 depends on
        the speed of the wind relative to the segment, v - u with u = theta' h_ij, and linearising
        F = rho (v - u)^2 A sin(phi) in u gives the damping torque (2 / v) sum_j F_j h_ij^2
        theta' = (2 Q_i / v) theta', taken times ``blade.air_damping`` (0.3 by default): in full it
        damps a blade to ~0.6 of critical, while grasses filmed in wind sway at their natural
        frequency, 0.8-2.5 Hz, damped to 0.1-0.3 of critical (docs/method.md: at 0.3 the tips'
        resonance, 1.0-1.6 Hz, lifts their response 2.4-6.5 times over the slow gusts'). It
        sways freely once the wind stops (v = 0). It is integrated implicitly,
        v_new = (p v + q y) / (1 + h c_aero / I): stable at any v, so both q and p carry the
        factor rc = 1 / (1 + h c_aero / I).
        Twist (eq 30): the same with K = twist_stiffness * mu_i(t); the face turning in the wind
        is not damped by it.
        """
        m, j0, j1 = b - a, split.j0, split.j1
        js, nj = slice(j0, j1), j1 - j0
        Q = self._aero_q(forcing, j0, S)
        hs = S.get("aero_lever", (m,))  # 2 h l_length / |v|: the last factor l_length of Q
        np.divide(F32(2.0 * h * self.air_damping), forcing.speed, out=hs)
        hs *= self._seg[a:b]
        rc = S.get("aero_factor", (nj, m))  # 1 / (1 + h c_aero / I)
        np.multiply(Q[js], self._inv_inertia[js, a:b], out=rc)
        rc *= hs
        rc += F32(1.0)
        np.divide(F32(1.0), rc, out=rc)
        q, p = S.get("osc_q", (nj, m)), S.get("osc_p", (nj, m))
        qt, pt = S.get("osc_q_twist", (nj, m)), S.get("osc_p_twist", (nj, m))
        np.multiply(kI, rc, out=q)
        q *= F32(h)
        rc *= F32(1.0 - h * self.alpha)
        np.multiply(q, F32(self.beta), out=p)
        np.subtract(rc, p, out=p)
        np.multiply(kI, F32(h * self.twist_ratio), out=qt)
        np.multiply(qt, F32(-self.beta), out=pt)
        pt += F32(1.0 - h * self.alpha)
        # Joints that do not oscillate take no sub-steps (v = 0, y held): they may be stiffer
        # than the sub-step can integrate, and their discarded values must stay finite.
        for coefficient in (q, p, qt, pt):
            coefficient *= split.swinging
        return q, p, qt, pt

    def _step_once(self, r: _Rows, coefficients: tuple, h: float, S: _Scratch) -> None:
        """One step a frame: the smooth update is eq 32's step with p = 0, q = f / h (v = f y / h
        is its rate, theta += h v its step), so each joint takes its own coefficients: the
        oscillator's (zero where it does not swing) plus the smooth ones (x = -f is 0 where it
        swings)."""
        q, p, qt, pt = coefficients
        nj, m = q.shape
        delta, delta_t = S.get("osc_delta", (nj, 2, m)), S.get("osc_delta_twist", (nj, m))
        np.multiply(r.x, F32(-1.0 / h), out=delta_t)
        q += delta_t
        np.multiply(r.xt, F32(-1.0 / h), out=delta_t)
        qt += delta_t
        np.multiply(r.gap, q[:, None, :], out=delta)
        r.vel *= p[:, None, :]
        r.vel += delta
        np.multiply(r.vel, F32(h), out=delta)
        r.bend += delta
        _clip(r.bend, *_limits(S, m, BEND_LIMIT))  # a forced swing can overshoot its target
        np.multiply(r.twist_gap, qt, out=delta_t)
        r.twist_vel *= pt
        r.twist_vel += delta_t
        np.multiply(r.twist_vel, F32(h), out=delta_t)
        r.twist += delta_t
        _clip(r.twist, *_limits(S, m, TWIST_LIMIT))

    def _substeps(self, r: _Rows, coefficients: tuple, h: float, dt: float, substeps: int, S: _Scratch) -> None:
        """Several sub-steps a frame: the swinging joints take eq 32's sub-steps on the gap, the
        others the smooth step (x, xt); blended by the masks."""
        q, p, qt, pt = coefficients
        nj, m = q.shape
        delta, delta_t = S.get("osc_delta", (nj, 2, m)), S.get("osc_delta_twist", (nj, m))
        smooth, smooth_t = S.get("smooth_step", (nj, 2, m)), S.get("smooth_step_twist", (nj, m))
        Y, Yt, vel, twist_vel = r.gap, r.twist_gap, r.vel, r.twist_vel
        np.multiply(Y, r.x[:, None, :], out=smooth)
        np.multiply(Yt, r.xt, out=smooth_t)
        qb, pb = q[:, None, :], p[:, None, :]
        for _ in range(substeps):
            np.multiply(Y, qb, out=delta)
            vel *= pb
            vel += delta
            np.multiply(vel, F32(h), out=delta)
            Y -= delta
            np.multiply(Yt, qt, out=delta_t)
            twist_vel *= pt
            twist_vel += delta_t
            np.multiply(twist_vel, F32(h), out=delta_t)
            Yt -= delta_t
        swinging, steady = r.swinging, r.steady
        swing_b, steady_b = swinging[:, None, :], steady[:, None, :]
        np.subtract(r.eq, Y, out=delta)
        _clip(delta, *_limits(S, m, BEND_LIMIT))  # a forced swing can overshoot its target
        r.bend -= smooth
        r.bend *= steady_b
        delta *= swing_b
        r.bend += delta
        np.subtract(r.twist_eq, Yt, out=delta_t)
        _clip(delta_t, *_limits(S, m, TWIST_LIMIT))
        r.twist -= smooth_t
        r.twist *= steady
        delta_t *= swinging
        r.twist += delta_t
        # rates: the oscillating joints keep their own (already in vel), the others -step / dt
        rate = S.get("smooth_rate_factor", (nj, m))
        np.multiply(steady, F32(-1.0 / dt), out=rate)
        smooth *= rate[:, None, :]
        vel *= swing_b
        vel += smooth
        smooth_t *= rate
        twist_vel *= swinging
        twist_vel += smooth_t
