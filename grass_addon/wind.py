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
origin), so every positional quantity is computed per column and per row and combined by
broadcasting: no per-cell Python loops, float32 results.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .errors import ParameterError

TURBULENCE_PURPOSE = 13  # np.random.default_rng([seed, 13, key]) draws the key lattices of eq 13
KEY_CACHE_SIZE = 6  # smoothed key lattices kept (4 are in use at any time)
MAX_LATTICE_UNITS = 1 << 21  # above this the units are made coarser (memory: 16 MB per key)
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


def _catmull_rom(u: float) -> np.ndarray:
    """Catmull-Rom weights of keys k-1, k, k+1, k+2 at fraction u in [0, 1) after key k."""
    u2, u3 = u * u, u * u * u
    return np.array([(-u3 + 2 * u2 - u) * 0.5, (3 * u3 - 5 * u2 + 2) * 0.5,
                     (-3 * u3 + 4 * u2 + u) * 0.5, (u3 - u2) * 0.5])


def _wrap_angle(a: float) -> float:
    """Angle in [-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)


def _parse_keys(keys: Sequence[Any] | None, params) -> np.ndarray:
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
                    else tuple(float(x) for x in row) for row in keys]
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

    def __init__(self, layout, params, keys=None):
        w = params.wind
        self.params = params
        self.kind = w.type
        self.seed = int(params.field.seed)
        self.cells_x, self.cells_y = int(layout.cells_x), int(layout.cells_y)
        self.n_cells = self.cells_x * self.cells_y
        self.cell_size = float(layout.cell_size)
        self.size = (self.cells_x * self.cell_size, self.cells_y * self.cell_size)
        # Cell centres of each column / row (float64), the field centred on the origin.
        self._col_x = (np.arange(self.cells_x) + 0.5) * self.cell_size - 0.5 * self.size[0]
        self._row_y = (np.arange(self.cells_y) + 0.5) * self.cell_size - 0.5 * self.size[1]

        # Mean wind keys (eq 12): times, speeds, directions in radians (unwrapped).
        table = _parse_keys(keys, params)
        self._key_t = table[:, 0].copy()
        self._key_speed = table[:, 1].copy()
        self._key_dir = np.radians(table[:, 2])
        self._build_advection_table()

        # Turbulence lattice (eq 13).
        self.turbulence_std = float(w.turbulence)
        self.period = float(w.turbulence_period)
        a = float(w.turbulence_scale)
        n = [max(3, math.ceil(s / a - 1e-9)) for s in self.size]
        while n[0] * n[1] > MAX_LATTICE_UNITS:
            # Memory limit (eq 13 needs one unit per a x a square): on a field too large for
            # that many units, the units are made coarser; the field then shows the finest
            # turbulence it can hold, with the same std.
            a *= math.sqrt(n[0] * n[1] / MAX_LATTICE_UNITS) * 1.001
            n = [max(3, math.ceil(s / a - 1e-9)) for s in self.size]
        self.unit = a
        self.units_x, self.units_y = n
        # Lattice coordinate of each cell column / row when nothing has moved: unit i has its
        # centre at edge + (i + 1/2) a, so with a == cell_size unit i is exactly cell i.
        self._lat_x = (np.arange(self.cells_x) + 0.5) * (self.cell_size / a) - 0.5
        self._lat_y = (np.arange(self.cells_y) + 0.5) * (self.cell_size / a) - 0.5
        self._rho_x = self._lag1_correlation(self.units_x)
        self._rho_y = self._lag1_correlation(self.units_y)
        self._keys_cache: OrderedDict[int, np.ndarray] = OrderedDict()

    # ------------------------------------------------------------------ mean wind (eq 12)

    def mean(self, t: float) -> tuple[float, float]:
        """Mean wind v-bar at time t: (speed m/s, direction rad towards, from +X, CCW).

        Piecewise-linear between keys, constant before the first and after the last key.
        """
        t = float(t)
        speed = float(np.interp(t, self._key_t, self._key_speed))
        direction = float(np.interp(t, self._key_t, self._key_dir))
        return speed, _wrap_angle(direction)

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

    @staticmethod
    def _lag1_correlation(n: int) -> float:
        """Correlation of neighbouring units after the periodic [1, 2, 1] / 4 filter (n >= 3)."""
        k = np.zeros(n)
        k[0], k[1], k[-1] = KERNEL_1D[1], KERNEL_1D[2], KERNEL_1D[0]
        return float(np.dot(k, np.roll(k, 1)) / np.dot(k, k))

    def _key_lattice(self, key: int) -> np.ndarray:
        """Smoothed turbulence lattice of time key ``key``: (units_y, units_x, 2) float32.

        Eq 13: v'(x_i, y_i) = (sum_B v_0 * lambda / (k d^2) + lambda v_0(x_i, y_i)) / sum of weights
        with the 1 2 1 / 2 4 2 / 1 2 1 weights, applied as [1, 2, 1] / 4 along each axis, wrapping
        around the periodic lattice. Input: independent N(0, 1) per unit and component.
        """
        cached = self._keys_cache.get(key)
        if cached is not None:
            self._keys_cache.move_to_end(key)
            return cached
        rng = np.random.default_rng([self.seed, TURBULENCE_PURPOSE, key % (1 << 64)])
        v0 = rng.standard_normal((self.units_y, self.units_x, 2), dtype=np.float32)
        lo, mid, hi = KERNEL_1D
        v = mid * v0 + lo * np.roll(v0, 1, axis=0) + hi * np.roll(v0, -1, axis=0)
        v = mid * v + lo * np.roll(v, 1, axis=1) + hi * np.roll(v, -1, axis=1)
        v = np.ascontiguousarray(v, dtype=np.float32)
        self._keys_cache[key] = v
        while len(self._keys_cache) > KEY_CACHE_SIZE:
            self._keys_cache.popitem(last=False)
        return v

    def _time_blend(self, t: float) -> np.ndarray:
        """Turbulence lattice at time t: keys every ``period`` s blended by Catmull-Rom.

        Independent keys blended with weights w keep the variance only if sum(w^2) = 1, so the
        weights are divided by sqrt(sum(w^2)): the std of v' is the same at every instant, and
        v' changes smoothly (C1) instead of flickering. The std reduction of eq 13 (6/16 per
        component) is undone here so that std(v') = wind.turbulence (eq 12).
        """
        u = t / self.period
        k = math.floor(u)
        weights = _catmull_rom(u - k)
        weights *= self.turbulence_std / (KERNEL_STD * math.sqrt(float(np.sum(weights * weights))))
        lattice = None
        for i, wt in enumerate(weights):
            if wt == 0.0:
                continue
            term = self._key_lattice(k - 1 + i)
            if lattice is None:
                lattice = term * np.float32(wt)
            else:
                lattice += term * np.float32(wt)
        return lattice

    def _axis_weights(self, base: np.ndarray, shift: float, n: int, rho: float):
        """Bilinear indices and weights along one axis of the periodic lattice.

        Between two units the interpolated value has variance (1-f)^2 + f^2 + 2 f (1-f) rho (rho:
        correlation of neighbouring units); the weights are divided by its square root so that
        v' keeps its std while the lattice drifts across the cells (no flicker of its strength).
        """
        pos = (base - shift % n) % n
        i0 = np.floor(pos)
        f = pos - i0
        i0 = i0.astype(np.intp) % n
        i1 = (i0 + 1) % n
        norm = 1.0 / np.sqrt((1 - f) ** 2 + f * f + 2 * f * (1 - f) * rho)
        return i0, i1, ((1 - f) * norm).astype(np.float32), (f * norm).astype(np.float32)

    def turbulence(self, t: float) -> np.ndarray:
        """Turbulent wind v' of every cell at time t (eq 13): (n_cells, 2) float32, m/s.

        Taylor's frozen turbulence: the lattice travels with the mean wind, so a cell at x sees
        the lattice at x - D(t), D(t) = integral_0^t v-bar dt' (bilinear, periodic).
        """
        t = float(t)
        if self.turbulence_std == 0.0:
            return np.zeros((self.n_cells, 2), dtype=np.float32)
        lattice = self._time_blend(t)
        shift = self.displacement(t) / self.unit
        iy0, iy1, wy0, wy1 = self._axis_weights(self._lat_y, shift[1], self.units_y, self._rho_y)
        ix0, ix1, wx0, wx1 = self._axis_weights(self._lat_x, shift[0], self.units_x, self._rho_x)
        # Rows first (cells_y, units_x * 2), then columns; the two components stay interleaved
        # and weights are repeated per component so every numpy loop runs over long rows.
        flat = lattice.reshape(self.units_y, self.units_x * 2)
        rows = flat[iy0]
        rows *= wy0[:, None]
        if np.any(wy1):
            rows += flat[iy1] * wy1[:, None]
        rows = rows.reshape(self.cells_y, self.units_x, 2)
        out = np.take(rows, ix0, axis=1).reshape(self.cells_y, self.cells_x * 2)
        out *= np.repeat(wx0, 2)[None, :]
        if np.any(wx1):
            more = np.take(rows, ix1, axis=1).reshape(self.cells_y, self.cells_x * 2)
            more *= np.repeat(wx1, 2)[None, :]
            out += more
        return out.reshape(self.n_cells, 2)

    # ------------------------------------------------------------------ the whole field (eq 12)

    def sample(self, t: float) -> np.ndarray:
        """Wind v = v-bar + v' of every cell at time t (eq 12), plus the type's gusts or vortex.

        (n_cells, 2) float32 C-contiguous, m/s, cell order c = cy * cells_x + cx.
        """
        t = float(t)
        out = self.turbulence(t)
        # Mean wind, uniform over the field (eq 12), added as one interleaved row per cell row.
        out.reshape(self.cells_y, self.cells_x * 2)[...] += np.tile(
            self._mean_vector(t).astype(np.float32), self.cells_x)[None, :]
        if self.kind == "blast":
            self._add_gusts(t, out)
        elif self.kind == "whirlwind":
            self._add_vortex(t, out)
        return out

    def gust_fronts(self, t: float) -> np.ndarray:
        """Blast: downwind positions s (m, from the field centre) of the fronts in the field at t.

        Front k starts at t_k = k * gust_interval, 3 widths upwind of the upwind field edge, and
        moves downwind at v-bar + gust_speed / 2 (its travel is the integral of that speed, so it
        follows changes of the mean wind smoothly) until it is 3 widths past the far edge.
        """
        w = self.params.wind
        g, width, interval = float(w.gust_speed), float(w.gust_width), float(w.gust_interval)
        if g == 0.0:
            return np.zeros(0)
        _, direction = self.mean(t)
        half = 0.5 * (self.size[0] * abs(math.cos(direction)) + self.size[1] * abs(math.sin(direction)))
        start = -half - 3.0 * width
        k_last = math.floor(t / interval)
        t_k = (k_last - np.arange(MAX_GUST_FRONTS, dtype=np.float64)) * interval
        _, s_k = self._integrals(t_k)
        _, s_t = self._integrals(np.array([t]))
        travel = (s_t[0] - s_k) + 0.5 * g * (t - t_k)
        travel = travel[travel <= 2.0 * half + 6.0 * width]
        return start + travel

    def _add_gusts(self, t: float, out: np.ndarray) -> None:
        """Blast: extra speed gust_speed * exp(-(s / gust_width)^2) along the wind direction.

        s is the cell's downwind coordinate minus a front's position. The fronts' profile is
        tabulated along s (width / 16 spacing; each front only within 4 widths, where
        exp(-16) ~ 1e-7 of its peak is left) and interpolated to the cells.
        """
        fronts = self.gust_fronts(t)
        if fronts.size == 0:
            return
        w = self.params.wind
        g, width = float(w.gust_speed), float(w.gust_width)
        _, direction = self.mean(t)
        c, s = math.cos(direction), math.sin(direction)
        half = 0.5 * (self.size[0] * abs(c) + self.size[1] * abs(s))
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
        row = ((self._row_y * s + half) * scale).astype(np.float32)
        col = (self._col_x * c * scale).astype(np.float32)
        pos = row[:, None] + col[None, :]
        np.clip(pos, 0.0, n - 1.0, out=pos)
        i0 = np.minimum(pos.astype(np.intp), n - 2)
        pos -= i0  # fraction between grid points
        prof = profile.astype(np.float32)
        extra = np.take(np.diff(prof), i0)
        extra *= pos
        extra += np.take(prof, i0)
        extra = extra.reshape(-1)
        out[:, 0] += extra * np.float32(c)
        out[:, 1] += extra * np.float32(s)

    def vortex_center(self, t: float) -> np.ndarray:
        """Whirlwind: centre (2,) of the vortex at t, carried by the mean wind from the origin
        at t = 0 and wrapped into the field, so it keeps coming back."""
        d = self.displacement(t)
        size = np.array(self.size)
        return (d + 0.5 * size) % size - 0.5 * size

    def _add_vortex(self, t: float, out: np.ndarray) -> None:
        """Whirlwind: Rankine vortex, counter-clockwise seen from above (+Z), core radius R.

        Tangential speed V r / R inside the core, V R / r outside (V = vortex_speed at r = R),
        plus a radial inflow of VORTEX_INFLOW times the tangential speed. Offsets use the
        nearest periodic image of the centre; past a quarter of the field the far field fades
        smoothly to zero at half the field, so the wrap-around leaves no seam.
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

        dx, hx = axis(self._col_x, centre[0], self.size[0])
        dy, hy = axis(self._row_y, centre[1], self.size[1])
        r2 = dy[:, None] ** 2 + dx[None, :] ** 2
        # |v_t| / r: V / R inside the core, V R / r^2 outside (no sqrt, finite at r = 0).
        q = np.float32(V * R) / np.maximum(r2, np.float32(R * R))
        q *= hy[:, None] * hx[None, :]
        a = np.float32(VORTEX_INFLOW)
        out[:, 0] += (q * (-dy[:, None] - a * dx[None, :])).reshape(-1)
        out[:, 1] += (q * (dx[None, :] - a * dy[:, None])).reshape(-1)
