"""The wind field of paper IV: v(x, y; t) = mean wind + turbulent wind (eq 12).

* Mean wind v-bar (eq 12): uniform over the field; speed and direction from ``wind.speed`` /
  ``wind.direction`` or from keys, piecewise-linear in time (direction along the shorter arc).
* Turbulent wind v' (eq 13): independent 2-D Gaussian vectors on a periodic lattice of square
  units (edge a = ``wind.turbulence_scale``), smoothed with the paper's 1 2 1 / 2 4 2 / 1 2 1
  weights, drawn afresh every ``wind.turbulence_period`` seconds and blended smoothly in time,
  and carried downwind by the mean wind (Taylor's frozen turbulence), so wind waves travel
  across the grass.
* Wind types (paper IV, Fig. 8): calm and the two breezes are mean + turbulence; ``blast`` adds
  gust fronts that sweep across the field; ``whirlwind`` adds a travelling Rankine vortex.

Cells lie on the layout's regular grid (row-major ``c = cy * cells_x + cx``, centred on the
origin; a camera's window is block-major, each block's cells a grid of their own), so every
positional quantity is computed per column and per row and combined by broadcasting: no
per-cell Python loops, float32 results, the same bits as the point-by-point ``sample``.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import gusts, loop
from .errors import ParameterError
from .schema import Params

TURBULENCE_PURPOSE = 13  # np.random.default_rng([seed, 13, key]) draws the key lattices of eq 13
KEY_CACHE_SIZE = 6  # smoothed key lattices kept (4 are in use at any time)
PATCHES_PER_KEY = 2  # regions of a key kept: a window's near cells and its far patches sample apart (far_sway.py)
BLOCK_GRIDS_KEPT = 2  # layouts whose cells' rows and columns are kept (a window's near cells and its far patches)
PATTERN_PERIOD_MAX = 1000.0  # m: gust fronts and the vortex repeat at most this far apart
STEPS_PER_SEGMENT = 64  # time grid of the advection integral between two mean-wind keys
MAX_GUST_FRONTS = 256  # blast: at most this many fronts (the most recent) are summed
VORTEX_INFLOW = 0.2  # whirlwind: radial inflow as a fraction of the tangential speed

# Eq 13 with the paper's values: B = the 8 surrounding units, lambda = 4, k = 2 / a^2.
# An edge neighbour (d = a) weighs lambda / (k d^2) = 2, a corner (d^2 = 2 a^2) weighs 1, the
# centre lambda = 4: the 1 2 1 / 2 4 2 / 1 2 1 kernel of Fig. 7, i.e. the outer product of the
# 1-D kernel [1, 2, 1] / 4 with itself. A unit-variance input keeps sum(w^2) = 6/16 of its
# variance per axis, 36/256 in 2-D, so the std of each component shrinks by 6/16.
KERNEL_1D = (0.25, 0.5, 0.25)
KERNEL_STD = 6.0 / 16.0
KERNEL_LAG1 = 2.0 / 3.0  # correlation of neighbouring units after [1, 2, 1] / 4: 0.25 / 0.375

MIX1, MIX2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def mix64(x: Any) -> Any:
    """splitmix64's finaliser: a bijective scramble of uint64 values, a scalar or an array
    (wrapping arithmetic)."""
    x = (x ^ (x >> np.uint64(30))) * MIX1
    x = (x ^ (x >> np.uint64(27))) * MIX2
    return x ^ (x >> np.uint64(31))


def unit_gaussians(seed: int, key: int, i0: int, j0: int, i1: int, j1: int) -> np.ndarray:
    """Independent N(0, 1) pairs of lattice units [i0, i1) x [j0, j1) for time key ``key``:
    (j1 - j0, i1 - i0, 2) float32. A counter-based generator: each unit's pair is a hash of
    (seed, TURBULENCE_PURPOSE, key, i, j) through Box-Muller, so a unit's value never depends on
    which other units are drawn with it."""
    with np.errstate(over="ignore"):
        base = mix64(np.uint64(seed % 2**64) * GOLDEN + np.uint64(TURBULENCE_PURPOSE))
        base = mix64(base ^ (np.uint64(key % 2**64) * MIX1))
        i = np.arange(i0, i1, dtype=np.int64).astype(np.uint64) * MIX2
        j = np.arange(j0, j1, dtype=np.int64).astype(np.uint64) * GOLDEN
        h = mix64(mix64(base ^ j[:, None]) ^ i[None, :])
    # two 26-bit uniforms: (0, 1] from the high bits (log stays finite), (0, 1) from the low bits
    u1 = ((h >> np.uint64(38)).astype(np.float64) + 1.0) * (1.0 / 2**26)
    u2 = ((h & np.uint64(0x3FFFFFF)).astype(np.float64) + 0.5) * (1.0 / 2**26)
    r = np.sqrt(-2.0 * np.log(u1))
    out = np.empty(h.shape + (2,), dtype=np.float32)
    out[..., 0] = r * np.cos(2.0 * np.pi * u2)
    out[..., 1] = r * np.sin(2.0 * np.pi * u2)
    return out


def _bilinear_weights(f: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the two units around fraction f, divided by the std of their blend.

    Between two units the interpolated value has variance (1-f)^2 + f^2 + 2 f (1-f) rho (rho:
    correlation of neighbouring units); the weights are divided by its square root so that v'
    keeps its std while the lattice drifts across the cells (no flicker of its strength).
    """
    g = np.float32(1.0) - f
    norm = g * g
    norm += f * f
    norm += np.float32(2.0 * rho) * f * g
    np.sqrt(norm, out=norm)
    np.reciprocal(norm, out=norm)
    return g * norm, f * norm


def _along_x(units: np.ndarray, index: np.ndarray, w0: np.ndarray, w1: np.ndarray, axis=None) -> np.ndarray:
    """units[index] * w0 + units[index + 1] * w1 (complex units; along ``axis``): the x part of
    the bilinear interpolation."""
    out = np.take(units, index, axis=axis)
    out *= w0
    right = np.take(units, index + 1, axis=axis)
    right *= w1
    out += right
    return out


def _catmull_rom(u: float) -> np.ndarray:
    """Catmull-Rom weights of keys k-1, k, k+1, k+2 at fraction u in [0, 1) after key k."""
    u2, u3 = u * u, u * u * u
    return np.array([(-u3 + 2 * u2 - u) * 0.5, (3 * u3 - 5 * u2 + 2) * 0.5,
                     (-3 * u3 + 4 * u2 + u) * 0.5, (u3 - u2) * 0.5])


def _wrap_angle(a: float) -> float:
    """Angle in [-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def _triple(row) -> tuple[float, float, float]:
    a, b, c = (float(x) for x in row)
    return a, b, c


def _parse_keys(keys: Sequence[Any] | None, params: Params) -> np.ndarray:
    """(m, 3) float64 rows time, speed, direction (degrees, unwrapped along the shorter arc).

    ``keys``: None (use params.wind.keys, or the constant wind.speed / wind.direction when there
    are none) or rows (time_s, speed_m_s, direction_deg), or dicts like params.wind.keys.
    """
    w = params.wind
    if keys is None:
        rows = [(k["time"], k["speed"], k["direction"]) for k in w.keys]
    else:
        try:
            rows = [(row["time"], row["speed"], row["direction"]) if isinstance(row, Mapping)
                    else _triple(row) for row in keys]
        except (TypeError, ValueError, KeyError):
            raise ParameterError("wind.keys", f"{keys!r} is not a sequence of (time_s, speed_m_s, "
                                 "direction_deg) rows") from None
    if not rows:
        rows = [(0.0, w.speed, w.direction)]
    table = np.array(rows, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != 3:
        raise ParameterError("wind.keys", "each key must be (time_s, speed_m_s, direction_deg)")
    if not np.all(np.isfinite(table)):
        raise ParameterError("wind.keys", "key times, speeds and directions must be finite numbers")
    if np.any(table[:, 1] < 0.0):
        raise ParameterError("wind.keys", "key speeds must be >= 0 m/s")
    if np.any(np.diff(table[:, 0]) <= 0.0):
        raise ParameterError("wind.keys", f"key times {table[:, 0].tolist()} must increase strictly")
    # Direction between keys turns along the shorter arc: unwrap each step into [-180, 180).
    step = (np.diff(table[:, 2]) + 180.0) % 360.0 - 180.0
    table[1:, 2] = table[0, 2] + np.cumsum(step)
    return table


class WindField:
    """Wind of every cell at any time t (seconds from the simulation start); see module doc."""

    def __init__(self, layout, params: Params, keys=None):
        w = params.wind
        self.params = params
        self.kind = w.type
        self.seed = int(params.field.seed)
        self.cell_size = float(layout.cell_size)
        self.size = tuple(float(v) for v in layout.size)  # the whole field's extent (m)
        self._xy = np.asarray(layout.cell_center, dtype=np.float64)  # default sample points

        # Mean wind keys (eq 12): times, speeds, directions in radians (unwrapped).
        table = _parse_keys(keys, params)
        self._key_t = table[:, 0].copy()
        self._key_speed = table[:, 1].copy()
        self._key_dir = np.radians(table[:, 2])
        self._build_advection_table()

        # Turbulence lattice (eq 13): unbounded, units of edge a. Units smaller than half a cell
        # would only alias into white noise at the cell centres (and cost memory), so a is at
        # least half a cell; the std of v' is the same.
        self.turbulence_std = float(w.turbulence)
        self.period = float(w.turbulence_period)
        self.unit = max(float(w.turbulence_scale), 0.5 * self.cell_size)
        self._keys_cache: OrderedDict[int, list[tuple[tuple[int, int, int, int], np.ndarray]]] = OrderedDict()
        # The whirlwind repeats with these periods (m) over very large fields (the fronts: _gust_half).
        self.vortex_period = tuple(min(v, PATTERN_PERIOD_MAX) for v in self.size)
        # Gust waves (gusts.py): a large pattern scaling the mean wind, carried downwind with it.
        self.gust_waves = float(w.gust_waves)
        self.gust_tile = (gusts.pattern(self.seed, float(w.direction), float(w.gust_stretch)) if self.gust_waves > 0.0
                          else None)
        self.gust_metres = gusts.tile_metres(params)
        self._block_grids: list[tuple[Any, tuple[np.ndarray, np.ndarray] | None]] = []
        self.loop = loop.loop_seconds(params)  # L (s): the wind repeats after it (loop.py); 0: never

    # ------------------------------------------------------------------ mean wind (eq 12)

    def mean(self, t: float) -> tuple[float, float]:
        """Mean wind v-bar at time t: (speed m/s, direction rad towards, from +X, CCW).

        Piecewise-linear between keys, constant before the first and after the last key.
        """
        t = float(t)
        speed = float(np.interp(t, self._key_t, self._key_speed))
        direction = float(np.interp(t, self._key_t, self._key_dir))
        return speed, _wrap_angle(direction)

    @property
    def keyed(self) -> bool:
        """The mean wind changes over time (keys of more than one speed or direction)."""
        return len(set(zip(self._key_speed.tolist(), self._key_dir.tolist()))) > 1

    def _mean_vector(self, t: float) -> np.ndarray:
        speed, direction = self.mean(t)
        return np.array([speed * math.cos(direction), speed * math.sin(direction)])

    def _build_advection_table(self) -> None:
        """Fixed time grid for D(t) = integral_0^t v-bar dt' and S(t) = integral_0^t |v-bar| dt'.

        Between grid points v-bar is taken linear, so D is integrated exactly from the grid
        values (trapezoid) and is C1 in t. A segment between two keys with a constant direction
        is exact with one step (speed is linear); a turning one gets one step per 1/256 turn
        of half a circle (at most STEPS_PER_SEGMENT), keeping the relative error below 1e-4.
        """
        kt = self._key_t
        if len(kt) == 1:
            self._tab_t = None
            return
        steps = np.clip(np.ceil(np.abs(np.diff(self._key_dir)) / (math.pi / 256)), 1, STEPS_PER_SEGMENT)
        steps = steps.astype(np.intp)
        seg = np.repeat(np.arange(len(steps)), steps)
        j = np.arange(int(steps.sum())) - np.repeat(np.cumsum(steps) - steps, steps)
        t = kt[seg] + (kt[seg + 1] - kt[seg]) * (j / steps[seg])
        t = np.append(t, kt[-1])
        speed = np.interp(t, kt, self._key_speed)
        direction = np.interp(t, kt, self._key_dir)
        vel = np.stack([speed * np.cos(direction), speed * np.sin(direction)], axis=1)
        h = np.diff(t)
        cum_d = np.concatenate([[[0.0, 0.0]], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * h[:, None], axis=0)])
        cum_s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * h)])
        self._tab_t, self._tab_vel, self._tab_speed = t, vel, speed
        self._tab_d, self._tab_s = cum_d, cum_s
        d0, s0 = self._integrals(np.zeros(1))
        self._tab_d = cum_d - d0[0]
        self._tab_s = cum_s - s0[0]

    def _integrals(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """D(t) (..., 2) and S(t) (...) in float64 for an array of times."""
        t = np.asarray(t, dtype=np.float64)
        if self._tab_t is None:
            speed, direction = self._key_speed[0], self._key_dir[0]
            vel = np.array([speed * math.cos(direction), speed * math.sin(direction)])
            return t[..., None] * vel, t * speed
        T = self._tab_t
        tc = np.clip(t, T[0], T[-1])
        j = np.clip(np.searchsorted(T, tc, side="right") - 1, 0, len(T) - 2)
        tau = tc - T[j]
        h = T[j + 1] - T[j]
        v0, v1 = self._tab_vel[j], self._tab_vel[j + 1]
        d = self._tab_d[j] + v0 * tau[..., None] + (v1 - v0) * (0.5 * tau * tau / h)[..., None]
        s0, s1 = self._tab_speed[j], self._tab_speed[j + 1]
        s = self._tab_s[j] + s0 * tau + (s1 - s0) * (0.5 * tau * tau / h)
        # Outside the keys the mean wind is constant: extend linearly.
        beyond = t - tc
        end = t > T[-1]
        d = d + np.where(end[..., None], self._tab_vel[-1], self._tab_vel[0]) * beyond[..., None]
        s = s + np.where(end, self._tab_speed[-1], self._tab_speed[0]) * beyond
        return d, s

    def displacement(self, t: float) -> np.ndarray:
        """D(t) = integral_0^t v-bar dt' (2,) float64: how far the mean wind has carried the air."""
        return self._integrals(np.array([float(t)]))[0][0]

    # ------------------------------------------------------------------ turbulence (eq 13)

    def _key_patch(self, key: int, i0: int, j0: int, i1: int, j1: int) -> np.ndarray:
        """Smoothed lattice of time key ``key`` over units [i0, i1) x [j0, j1): (j1-j0, i1-i0, 2) float32.

        Eq 13: v'(x_i, y_i) = (sum_B v_0 * lambda / (k d^2) + lambda v_0(x_i, y_i)) / sum of weights
        with the 1 2 1 / 2 4 2 / 1 2 1 weights, applied as [1, 2, 1] / 4 along each axis. The
        unsmoothed v_0 of a unit is a hash of (seed, key, unit), so any unit of the unbounded
        lattice has the same value whichever patch computes it.
        """
        kept = self._keys_cache.get(key, [])
        for (ci0, cj0, ci1, cj1), patch in kept:
            if ci0 <= i0 and cj0 <= j0 and i1 <= ci1 and j1 <= cj1:
                self._keys_cache.move_to_end(key)
                return patch[j0 - cj0:j1 - cj0, i0 - ci0:i1 - ci0]
        # Grow the patch by a margin: the region drifts with the mean wind between calls.
        mx, my = max(8, (i1 - i0) // 4), max(8, (j1 - j0) // 4)
        ci0, cj0, ci1, cj1 = i0 - mx, j0 - my, i1 + mx, j1 + my
        v0 = unit_gaussians(self.seed, key, ci0 - 1, cj0 - 1, ci1 + 1, cj1 + 1)
        lo, mid, hi = (np.float32(k) for k in KERNEL_1D)
        v = mid * v0[1:-1] + lo * v0[:-2] + hi * v0[2:]
        v = mid * v[:, 1:-1] + lo * v[:, :-2] + hi * v[:, 2:]
        patch = np.ascontiguousarray(v, dtype=np.float32)
        self._keys_cache[key] = [((ci0, cj0, ci1, cj1), patch)] + kept[:PATCHES_PER_KEY - 1]
        self._keys_cache.move_to_end(key)
        while len(self._keys_cache) > KEY_CACHE_SIZE:
            self._keys_cache.popitem(last=False)
        return patch[j0 - cj0:j1 - cj0, i0 - ci0:i1 - ci0]

    def _time_blend(self, t: float, region: tuple[int, int, int, int]) -> np.ndarray:
        """Turbulence lattice at time t over ``region``: keys every ``period`` s blended by Catmull-Rom.

        Independent keys blended with weights w keep the variance only if sum(w^2) = 1, so the
        weights are divided by sqrt(sum(w^2)): the std of v' is the same at every instant, and
        v' changes smoothly (C1) instead of flickering. The std reduction of eq 13 (6/16 per
        component) is undone here so that std(v') = wind.turbulence (eq 12).
        """
        u = t / self.period
        k = math.floor(u)
        weights = _catmull_rom(u - k)
        weights *= self.turbulence_std / (KERNEL_STD * math.sqrt(float(np.sum(weights * weights))))
        lattice: np.ndarray | None = None
        for i, wt in enumerate(weights):
            if wt == 0.0:
                continue
            term = self._key_patch(k - 1 + i, *region)
            if lattice is None:
                lattice = term * np.float32(wt)
            else:
                lattice += term * np.float32(wt)
        assert lattice is not None  # (Catmull-Rom's four weights are never all zero)
        return lattice

    def _lattice_frame(self, t: float, xs: np.ndarray, ys: np.ndarray):
        """Where coordinates xs and ys fall on the lattice at time t: (lattice (H, W) complex64, the
        blended units x + iy over the region they need, column and row of the lower unit, and the
        bilinear weights (wx0, wx1, wy0, wy1), float32). Element-wise per coordinate."""
        shift = self.displacement(t)
        inverse = 1.0 / self.unit
        ux = np.asarray(xs, dtype=np.float64) * inverse
        ux -= shift[0] * inverse + 0.5
        uy = np.asarray(ys, dtype=np.float64) * inverse
        uy -= shift[1] * inverse + 0.5
        fx0, fy0 = np.floor(ux), np.floor(uy)
        i0, j0 = int(fx0.min()), int(fy0.min())
        region = (i0, j0, int(fx0.max()) + 2, int(fy0.max()) + 2)
        lattice = np.ascontiguousarray(self._time_blend(t, region)).view(np.complex64)[..., 0]
        wx0, wx1 = _bilinear_weights((ux - fx0).astype(np.float32), KERNEL_LAG1)
        wy0, wy1 = _bilinear_weights((uy - fy0).astype(np.float32), KERNEL_LAG1)
        return lattice, (fx0 - i0).astype(np.intp), (fy0 - j0).astype(np.intp), wx0, wx1, wy0, wy1

    def turbulence(self, t: float, xy: np.ndarray | None = None) -> np.ndarray:
        """Turbulent wind v' at time t (eq 13): (m, 2) float32, m/s, at the points ``xy`` (m, 2)
        (default: the layout's cell centres).

        Taylor's frozen turbulence: the lattice travels with the mean wind, so a point at x sees
        the lattice at x - D(t), D(t) = integral_0^t v-bar dt' (bilinear). Unit i of the lattice
        has its centre at (i + 1/2) a. Every point's value depends on that point alone (the same
        arithmetic, element by element, whichever points are sampled with it).
        """
        t = float(t)
        xy = self._xy if xy is None else np.asarray(xy, dtype=np.float64)
        if self.turbulence_std == 0.0 or xy.shape[0] == 0:
            return np.zeros((xy.shape[0], 2), dtype=np.float32)
        lattice, column, row, wx0, wx1, wy0, wy1 = self._lattice_frame(t, xy[:, 0], xy[:, 1])
        units = lattice.ravel()  # one gather per corner
        corner = row * lattice.shape[1] + column
        out = _along_x(units, corner, wx0, wx1)
        out *= wy0
        upper = _along_x(units, corner + lattice.shape[1], wx0, wx1)
        upper *= wy1
        out += upper
        return out.view(np.float32).reshape(-1, 2)

    def _turbulence_grid(self, t: float, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """``turbulence`` at every point of the grid xs (columns) x ys (rows): (rows, cols, 2).

        Each column's and row's coordinate and weights are computed once, and the x interpolation
        once per lattice row and column, in the same order of operations as ``turbulence``, so every
        point gets the same bits as there."""
        lattice, column, row, wx0, wx1, wy0, wy1 = self._lattice_frame(t, xs, ys)
        along = _along_x(lattice, column, wx0, wx1, axis=1)  # (H, cols): every lattice row, every column
        out = np.take(along, row, axis=0)  # (rows, cols)
        out *= wy0[:, None]
        upper = np.take(along, row + 1, axis=0)
        upper *= wy1[:, None]
        out += upper
        return out.view(np.float32).reshape(out.shape + (2,))

    def _turbulence_blocks(self, t: float, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """``turbulence`` at the cells of blocks whose cells are grids: block b's cell (r, c) at
        (xs[b, c], ys[b, r]): (blocks, rows, cols, 2). Each column's and row's unit and weights
        are computed once; every cell's corner and blend are the same operations as in
        ``turbulence``, so every cell gets the same bits as there."""
        lattice, column, row, wx0, wx1, wy0, wy1 = self._lattice_frame(t, xs.ravel(), ys.ravel())
        blocks, n = xs.shape
        units = lattice.ravel()
        corner = (row * lattice.shape[1]).reshape(blocks, n, 1) + column.reshape(blocks, 1, n)
        wx0, wx1 = wx0.reshape(blocks, 1, n), wx1.reshape(blocks, 1, n)
        out = _along_x(units, corner, wx0, wx1)
        out *= wy0.reshape(blocks, n, 1)
        upper = _along_x(units, corner + lattice.shape[1], wx0, wx1)
        upper *= wy1.reshape(blocks, n, 1)
        out += upper
        return out.view(np.float32).reshape(out.shape + (2,))

    def _looped(self, t: float, evaluate) -> np.ndarray:
        """``evaluate(t)`` (the wind at t), looped with period ``self.loop`` (``loop.blend``)."""
        tau, w = loop.phase(float(t), self.loop)
        before = tau - self.loop
        return loop.blend(evaluate(tau), self._mean_vector(tau), evaluate(before), self._mean_vector(before),
                          self._mean_vector(tau), w)

    def sample_layout(self, t: float, layout) -> np.ndarray:
        """``sample(t, layout.cell_center)``, the same bits, computed per row and column: on a
        whole-field layout (cells row-major on the field's grid) over the field's rows and
        columns; on a window of blocks (block-major, each block's cells a grid) over each
        block's (``_block_grid``). Looped with ``simulation.loop``."""
        if self.loop:
            return self._looped(t, lambda u: self._sample_layout(u, layout))
        return self._sample_layout(t, layout)

    def _sample_layout(self, t: float, layout) -> np.ndarray:
        t = float(t)
        whole = layout.n_cells == layout.cells_x * layout.cells_y and layout.n_cells > 0
        xy = np.asarray(layout.cell_center, dtype=np.float64)
        if whole and self.turbulence_std != 0.0:
            grid = self._turbulence_grid(t, xy[: layout.cells_x, 0], xy[:: layout.cells_x, 1])
            return self._add_mean_and_type(t, xy, np.ascontiguousarray(grid.reshape(-1, 2)))
        blocks = None if whole else self._block_grid(layout)
        if blocks is None:
            return self._add_mean_and_type(t, xy, self.turbulence(t, xy))
        if self.turbulence_std == 0.0:
            out = np.zeros((xy.shape[0], 2), dtype=np.float32)
        else:
            out = self._turbulence_blocks(t, *blocks).reshape(-1, 2)
        return self._add_mean_and_type(t, xy, out, blocks)

    def _block_grid(self, layout) -> tuple[np.ndarray, np.ndarray] | None:
        """(xs, ys), (blocks, cells_per_block) float64: the column x and row y of each block's
        cells, when the layout's cells are block-major and each block's are a row-major grid
        (a window's layout); None otherwise. Kept for the last BLOCK_GRIDS_KEPT layouts asked about
        (a window's near cells and far patches are two, sampled in turn every frame)."""
        for kept, grid in self._block_grids:
            if kept is layout:
                return grid
        n = int(layout.cells_per_block)
        centres = np.asarray(layout.cell_center, dtype=np.float64)
        grid = None
        if n > 0 and layout.n_cells > 0 and centres.shape[0] == layout.n_blocks * n * n:
            cells = centres.reshape(-1, n, n, 2)
            xs, ys = cells[:, 0, :, 0], cells[:, :, 0, 1]
            if np.array_equal(cells[..., 0], np.broadcast_to(xs[:, None, :], cells.shape[:3])) and \
                    np.array_equal(cells[..., 1], np.broadcast_to(ys[:, :, None], cells.shape[:3])):
                grid = (np.ascontiguousarray(xs), np.ascontiguousarray(ys))
        self._block_grids = [(layout, grid)] + self._block_grids[:BLOCK_GRIDS_KEPT - 1]
        return grid

    # ------------------------------------------------------------------ the whole field (eq 12)

    def sample(self, t: float, xy: np.ndarray | None = None) -> np.ndarray:
        """Wind v = v-bar + v' at time t (eq 12), plus the type's gusts or vortex, at the points
        ``xy`` (m, 2) (default: the layout's cell centres, in its cell order).

        (m, 2) float32 C-contiguous, m/s; each point's value depends on that point and t alone.
        Looped with ``simulation.loop`` (``loop.py``).
        """
        xy = self._xy if xy is None else np.asarray(xy, dtype=np.float64)
        if self.loop:
            return self._looped(t, lambda u: self._add_mean_and_type(u, xy, self.turbulence(u, xy)))
        t = float(t)
        return self._add_mean_and_type(t, xy, self.turbulence(t, xy))

    def _add_mean_and_type(self, t: float, xy: np.ndarray, out: np.ndarray,
                           blocks: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """``out`` (v' at points ``xy``) plus the mean wind (eq 12) and the type's gusts or vortex.
        ``blocks``: the points' ``_block_grid`` when they have one (the same bits, sooner)."""
        mean = self._mean_vector(t).astype(np.float32)
        # (per component: numpy broadcasting along a last axis of 2 is several times slower)
        u, v = out[:, 0], out[:, 1]
        u += mean[0]  # uniform over the field (eq 12)
        v += mean[1]
        if self.gust_tile is not None:  # the gust waves scale it by gust_waves (2 g - 1) where they pass (gusts.py)
            if blocks is None:
                g = gusts.sample(self.gust_tile, xy, self.gust_metres, self.displacement(t))
            else:
                xs, ys = blocks
                g = gusts.sample_blocks(self.gust_tile, xs, ys, self.gust_metres, self.displacement(t)).ravel()
            g *= np.float32(2.0 * self.gust_waves)
            g -= np.float32(self.gust_waves)
            u += g * mean[0]
            v += g * mean[1]
        if self.kind == "blast":
            self._add_gusts(t, xy, out)
        elif self.kind == "whirlwind":
            self._add_vortex(t, xy, out)
        return out

    def _gust_half(self, direction: float) -> float:
        """Half the field's extent along the wind, at most half of PATTERN_PERIOD_MAX."""
        half = 0.5 * (self.size[0] * abs(math.cos(direction)) + self.size[1] * abs(math.sin(direction)))
        return min(half, 0.5 * PATTERN_PERIOD_MAX)

    def gust_fronts(self, t: float) -> np.ndarray:
        """Blast: downwind positions s (m, from the field centre) of the fronts in the field at t.

        Front k starts at t_k = k * gust_interval, 3 widths upwind of the upwind field edge, and
        moves downwind at v-bar + gust_speed / 2 (its travel is the integral of that speed, so it
        follows changes of the mean wind smoothly) until it is 3 widths past the far edge. On a
        field longer than PATTERN_PERIOD_MAX along the wind the fronts repeat every
        2 half + 6 widths downwind (``half`` capped), so every cell sees them.
        """
        w = self.params.wind
        g, width, interval = float(w.gust_speed), float(w.gust_width), float(w.gust_interval)
        if g == 0.0:
            return np.zeros(0)
        _, direction = self.mean(t)
        half = self._gust_half(direction)
        start = -half - 3.0 * width
        k_last = math.floor(t / interval)
        t_k = (k_last - np.arange(MAX_GUST_FRONTS, dtype=np.float64)) * interval
        _, s_k = self._integrals(t_k)
        _, s_t = self._integrals(np.array([t]))
        travel = (s_t[0] - s_k) + 0.5 * g * (t - t_k)
        travel = travel[travel <= 2.0 * half + 6.0 * width]
        return start + travel

    def _add_gusts(self, t: float, xy: np.ndarray, out: np.ndarray) -> None:
        """Blast: extra speed gust_speed * exp(-(s / gust_width)^2) along the wind direction.

        s is the point's downwind coordinate minus a front's position. The fronts' profile is
        tabulated along s (width / 16 spacing; each front only within 4 widths, where
        exp(-16) ~ 1e-7 of its peak is left) and interpolated to the points.
        """
        fronts = self.gust_fronts(t)
        if fronts.size == 0:
            return
        w = self.params.wind
        g, width = float(w.gust_speed), float(w.gust_width)
        _, direction = self.mean(t)
        c, s = math.cos(direction), math.sin(direction)
        half = self._gust_half(direction) + 3.0 * width  # the fronts' whole course, one period
        n = int(min(65536, max(2, math.ceil(2.0 * half / (width / 16.0)) + 1)))
        grid = np.linspace(-half, half, n)
        scale = (n - 1) / (2.0 * half)
        reach = int(math.ceil(4.0 * width * scale))
        centre = np.rint((fronts + half) * scale)
        lo = np.clip(centre - reach, 0, n).astype(np.intp)
        hi = np.clip(centre + reach + 1, 0, n).astype(np.intp)
        near = lo[:, None] + np.arange(int(np.max(hi - lo)))  # at most 2 * 64 + 1 points each
        inside = near < hi[:, None]
        near = near[inside]
        bumps = np.exp(-(((grid[near] - np.broadcast_to(fronts[:, None], inside.shape)[inside]) / width) ** 2))
        profile = g * np.bincount(near, weights=bumps, minlength=n)
        downwind = xy[:, 0] * c + xy[:, 1] * s
        downwind = np.mod(downwind + half, 2.0 * half)  # one period of the fronts' course
        pos = (downwind * scale).astype(np.float32)
        np.clip(pos, 0.0, n - 1.0, out=pos)
        i0 = np.minimum(pos.astype(np.intp), n - 2)
        pos -= i0  # fraction between grid points
        prof = profile.astype(np.float32)
        extra = np.take(np.diff(prof), i0)
        extra *= pos
        extra += np.take(prof, i0)
        out[:, 0] += extra * np.float32(c)
        out[:, 1] += extra * np.float32(s)

    def vortex_center(self, t: float) -> np.ndarray:
        """Whirlwind: centre (2,) of the vortex at t, carried by the mean wind from the origin
        at t = 0 and wrapped into the field (or into PATTERN_PERIOD_MAX), so it keeps coming back."""
        d = self.displacement(t)
        size = np.array(self.vortex_period)
        return (d + 0.5 * size) % size - 0.5 * size

    def _add_vortex(self, t: float, xy: np.ndarray, out: np.ndarray) -> None:
        """Whirlwind: Rankine vortex, counter-clockwise seen from above (+Z), core radius R.

        Tangential speed V r / R inside the core, V R / r outside (V = vortex_speed at r = R),
        plus a radial inflow of VORTEX_INFLOW times the tangential speed. Offsets use the
        nearest periodic image of the centre (period: the field, at most PATTERN_PERIOD_MAX);
        past a quarter of the period the far field fades smoothly to zero at half of it, so the
        wrap-around leaves no seam.
        """
        w = self.params.wind
        V, R = float(w.vortex_speed), float(w.vortex_radius)
        if V == 0.0:
            return
        centre = self.vortex_center(t)

        def axis(coords: np.ndarray, c: float, size: float) -> tuple[np.ndarray, np.ndarray]:
            d = coords - c
            d -= size * np.round(d / size)
            u = np.clip((np.abs(d) - 0.25 * size) / (0.25 * size), 0.0, 1.0)
            return d.astype(np.float32), (1.0 - u * u * (3.0 - 2.0 * u)).astype(np.float32)

        dx, hx = axis(xy[:, 0], centre[0], self.vortex_period[0])
        dy, hy = axis(xy[:, 1], centre[1], self.vortex_period[1])
        r2 = dy * dy + dx * dx
        # |v_t| / r: V / R inside the core, V R / r^2 outside (no sqrt, finite at r = 0).
        q = np.float32(V * R) / np.maximum(r2, np.float32(R * R))
        q *= hy * hx
        a = np.float32(VORTEX_INFLOW)
        out[:, 0] += q * (-dy - a * dx)
        out[:, 1] += q * (dx - a * dy)
