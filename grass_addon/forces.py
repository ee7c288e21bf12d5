"""Blender's force fields blowing the grass (issue #19): Wind, Force, Vortex and Turbulence.

Each effector adds, at every cell (at half the grass's height), the horizontal part of the force
Blender's own effector code gives a particle there, read as wind in m/s (strength 1 = 1 m/s at
full effect). The settings mean what they mean in Blender:

* the point's vector from the field's centre ``v`` and distance ``d``: ``|v|`` for a point shape,
  the distance along the field's Z axis for a plane;
* falloff ``(1 + d - min)^-power``: full effect within ``min_distance`` (when used), none beyond
  ``max_distance`` (when used); ``sphere`` by ``d``, ``tube`` by the distance along Z times the
  same law across it (radial settings), ``cone`` by the distance along Z times the law of the
  angle from Z in degrees;
* wind: along the field's Z axis; force: along ``v`` (positive strength pushes away); vortex:
  around the Z axis, ``Z x v`` (positive strength turns counter-clockwise seen from +Z);
  turbulence: Blender's noise vector field, fixed to the field: each component three octaves of
  Perlin's improved noise at the point's offset from the field plus its Z axis, over ``size``
  (0: 1 m, as Blender); in Blender the bridge hands in Blender's own noise (``turbulence=``), else
  ``perlin`` stands in: the same noise with Windgrass's own permutation;
* noise: the strength changes randomly by up to ``noise`` times it (smoothly, a few times a second).

The effectors at time t come from a track (``SampledEffectors``: Blender's, once per frame) or
are fixed (a scene file's ``[[effectors]]``), so frame N is still a function of the scene and N.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, replace

import numpy as np

from .errors import ParameterError
from .interaction import nearest_sample
from .schema import Params

NOISE_RATE = 4.0  # Hz: how fast an effector's noise changes


@dataclass(frozen=True)
class Effector:
    """One force field at one instant; ``matrix`` (4, 4) its world transform (Z axis: its direction)."""

    kind: str  # wind | force | vortex | turbulence
    matrix: np.ndarray
    strength: float
    shape: str = "point"  # point | plane
    power: float = 0.0
    falloff_type: str = "sphere"  # sphere | tube | cone
    min_distance: float = 0.0
    use_min: bool = False
    max_distance: float = 0.0
    use_max: bool = False
    radial_power: float = 0.0
    radial_min: float = 0.0
    use_radial_min: bool = False
    radial_max: float = 0.0
    use_radial_max: bool = False
    noise: float = 0.0
    size: float = 1.0
    seed: int = 1

    def with_matrix(self, matrix) -> Effector:
        return replace(self, matrix=np.asarray(matrix, np.float64))


def euler_matrix(position, rotation_deg) -> np.ndarray:
    """(4, 4) world matrix of an object at ``position`` turned by Euler XYZ ``rotation_deg``
    (Blender's default rotation mode: X first, then Y, then Z)."""
    x, y, z = (math.radians(a) for a in rotation_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    m[:3, 3] = position
    return m


def from_row(row) -> Effector:
    """A scene file's ``[[effectors]]`` row (validated by the schema)."""
    return Effector(kind=row["type"], matrix=euler_matrix(row["position"], row["rotation"]),
                    strength=float(row["strength"]), shape=row["shape"], power=float(row["falloff"]),
                    falloff_type=row["falloff_type"], min_distance=float(row["min_distance"]),
                    use_min=row["min_distance"] > 0.0, max_distance=float(row["max_distance"]),
                    use_max=row["max_distance"] > 0.0, radial_power=float(row["falloff"]), noise=float(row["noise"]),
                    size=float(row["size"]), seed=int(row["seed"]))


class FixedEffectors:
    """Effectors that do not change over time (a scene file's)."""

    def __init__(self, effectors):
        self.effectors = list(effectors)

    def at(self, t: float) -> list[Effector]:
        return self.effectors


class SampledEffectors:
    """Effectors sampled at ``times`` (ascending; Blender's, once per frame): those of the
    sample nearest to t (an effector switched off at a sample is absent from it)."""

    def __init__(self, times, samples, turbulence=None):
        self.times = np.asarray(times, np.float64)
        self.samples = [list(s) for s in samples]
        self.turbulence = turbulence  # Blender's noise of a Turbulence (turbulence_vector's arguments), or None

    def at(self, t: float) -> list[Effector]:
        if not len(self.times):
            return []
        return self.samples[nearest_sample(self.times, t)]


class JoinedEffectors:
    """The effectors of several sources (Blender's sampled ones and a scene file's)."""

    def __init__(self, *sources):
        self.sources = sources
        self.turbulence = next((t for t in (getattr(s, "turbulence", None) for s in sources) if t), None)

    def at(self, t: float) -> list[Effector]:
        return [e for s in self.sources for e in s.at(t)]


def join(*sources):
    """One source of the effectors of ``sources`` (None for none)."""
    found = [s for s in sources if s is not None]
    return None if not found else found[0] if len(found) == 1 else JoinedEffectors(*found)


def effectors_from_params(params: Params) -> FixedEffectors | None:
    rows = params.interaction.effectors
    return FixedEffectors([from_row(r) for r in rows]) if rows else None


# ------------------------------------------------------------------------------------------------
# Blender's falloff and forces


def falloff_law(d: np.ndarray, use_min: bool, minimum: float, use_max: bool, maximum: float,
                power: float) -> np.ndarray:
    """Blender's falloff function: 0 beyond the maximum, 1 within the minimum, else
    (1 + d - min)^-power."""
    d = np.asarray(d, np.float64)
    low = minimum if use_min else 0.0
    out = np.power(np.maximum(1.0 + d - low, 1e-9), -power) if power else np.ones_like(d)
    if use_min:
        out = np.where(d < minimum, 1.0, out)
    if use_max:
        out = np.where(d > maximum, 0.0, out)
    return out


def _geometry(e: Effector, points: np.ndarray):
    """(vector from the field to each point (m, 3), distance (m,), axis (3,), along-axis (m,))."""
    origin, axis = e.matrix[:3, 3], e.matrix[:3, 2] / max(np.linalg.norm(e.matrix[:3, 2]), 1e-12)
    vec = points - origin
    along = vec @ axis
    if e.shape == "plane":
        return axis[None, :] * along[:, None], np.abs(along), axis, along
    return vec, np.linalg.norm(vec, axis=1), axis, along


def falloff(e: Effector, points: np.ndarray, geometry=None) -> np.ndarray:
    """(m,) the effect's share at ``points`` (Blender's effector_falloff); ``geometry``: their
    ``_geometry`` when the caller has it."""
    vec, distance, axis, along = _geometry(e, points) if geometry is None else geometry
    if e.falloff_type == "sphere":
        return falloff_law(distance, e.use_min, e.min_distance, e.use_max, e.max_distance, e.power)
    out = falloff_law(np.abs(along), e.use_min, e.min_distance, e.use_max, e.max_distance, e.power)
    full = points - e.matrix[:3, 3]
    if e.falloff_type == "tube":
        radial = np.linalg.norm(full - along[:, None] * axis[None, :], axis=1)
    else:  # cone: the angle from the axis, in degrees
        length = np.maximum(np.linalg.norm(full, axis=1), 1e-12)
        radial = np.degrees(np.arccos(np.clip(along / length, -1.0, 1.0)))
    return out * falloff_law(radial, e.use_radial_min, e.radial_min, e.use_radial_max, e.radial_max,
                             e.radial_power)


def _hash(ix, iy, iz, seed: int) -> np.ndarray:
    """Deterministic pseudo-random values in [-1, 1) of integer lattice points."""
    h = (ix.astype(np.int64) * 73856093) ^ (iy.astype(np.int64) * 19349663) ^ (iz.astype(np.int64) * 83492791) \
        ^ (seed * 2654435761)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return (h & 0xFFFFFF).astype(np.float64) / float(1 << 23) - 1.0


def value_noise(p: np.ndarray, seed: int) -> np.ndarray:
    """(m,) smooth noise in [-1, 1] of points (m, 3): trilinear between hashed lattice values."""
    base = np.floor(p)
    f = p - base
    f = f * f * (3.0 - 2.0 * f)
    i = base.astype(np.int64)
    out = np.zeros(len(p))
    weights = [(1 - f, f)[k] for k in (0, 1)]  # weights[corner][:, axis]
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = weights[dx][:, 0] * weights[dy][:, 1] * weights[dz][:, 2]
                out += w * _hash(i[:, 0] + dx, i[:, 1] + dy, i[:, 2] + dz, seed)
    return out


# Perlin's improved noise (2002): a permutation of 0..255 (twice, so that indices need no wrap)
# hashes the lattice corners to one of 12 gradient directions (16 cases), blended by the quintic fade.
_PERMUTATION = np.tile(np.random.default_rng(0x7E4B).permutation(256), 2).astype(np.int64)
TURBULENCE_OCTAVES = 3  # Blender's turbulence field: octaves 1, 2, 4 at amplitudes 1, 1/2, 1/4


def _gradient(h: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Perlin's grad(): the dot product of corner offset (x, y, z) with the gradient ``h & 15``."""
    h = h & 15
    u = np.where(h < 8, x, y)
    v = np.where(h < 4, y, np.where((h == 12) | (h == 14), x, z))
    return np.where(h & 1, -u, u) + np.where(h & 2, -v, v)


def perlin(p: np.ndarray) -> np.ndarray:
    """(m,) Perlin's improved noise of points (m, 3): about -1..1, 0 on the integer lattice."""
    base = np.floor(p)
    x, y, z = (p - base).T
    fx, fy, fz = ((f * f * f * (f * (f * 6.0 - 15.0) + 10.0)) for f in (x, y, z))
    i = base.astype(np.int64) & 255
    P = _PERMUTATION
    a, b = P[i[:, 0]] + i[:, 1], P[i[:, 0] + 1] + i[:, 1]
    aa, ab, ba, bb = P[a] + i[:, 2], P[a + 1] + i[:, 2], P[b] + i[:, 2], P[b + 1] + i[:, 2]

    def lerp(t, lo, hi):
        return lo + t * (hi - lo)

    near = lerp(fy, lerp(fx, _gradient(P[aa], x, y, z), _gradient(P[ba], x - 1, y, z)),
                lerp(fx, _gradient(P[ab], x, y - 1, z), _gradient(P[bb], x - 1, y - 1, z)))
    far = lerp(fy, lerp(fx, _gradient(P[aa + 1], x, y, z - 1), _gradient(P[ba + 1], x - 1, y, z - 1)),
               lerp(fx, _gradient(P[ab + 1], x, y - 1, z - 1), _gradient(P[bb + 1], x - 1, y - 1, z - 1)))
    return lerp(fz, near, far)


def turbulence_vector(q: np.ndarray, noise=perlin) -> np.ndarray:
    """(m, 3) Blender's turbulence at the offsets ``q`` (m, 3) already over the eddy size: each
    component the octaves of ``noise`` at (x, y, z), (y, z, x) and (z, x, y), averaged by amplitude."""
    out = np.zeros((len(q), 3))
    for k, order in enumerate(((0, 1, 2), (1, 2, 0), (2, 0, 1))):
        turned = q[:, order]
        for octave in range(TURBULENCE_OCTAVES):
            out[:, k] += 0.5 ** octave * noise(turned * 2.0 ** octave)
    return out / sum(0.5 ** octave for octave in range(TURBULENCE_OCTAVES))


def turbulence_offsets(e: Effector, points: np.ndarray) -> np.ndarray:
    """Where Blender reads its turbulence noise for ``points``: their offset from the field's centre
    plus its Z axis, over the eddy size (a size of 0, as Add > Force Field gives it, is 1 m)."""
    axis = e.matrix[:3, 2] / max(np.linalg.norm(e.matrix[:3, 2]), 1e-12)
    return (points - e.matrix[:3, 3] + axis) / (e.size if e.size > 0.0 else 1.0)


def force(e: Effector, points: np.ndarray, t: float, turbulence=turbulence_vector) -> np.ndarray:
    """(m, 3) the force field's push at ``points`` at time ``t``, in m/s of wind; ``turbulence``:
    the noise field of a Turbulence (``turbulence_vector``'s arguments; Blender's in Blender)."""
    geometry = _geometry(e, points)
    vec, distance, axis, _ = geometry
    share = falloff(e, points, geometry)
    strength = np.full(len(points), e.strength)
    if e.noise > 0.0:
        cell = np.column_stack([points[:, :2] * 0.5, np.full(len(points), t * NOISE_RATE)])
        strength = strength + e.noise * abs(e.strength) * value_noise(cell, e.seed)
    if e.kind == "wind":
        direction = np.broadcast_to(axis, points.shape)
    elif e.kind == "force":
        direction = vec / np.maximum(distance, 1e-9)[:, None]
    elif e.kind == "vortex" and e.shape == "plane":
        return _plane_vortex(e, points, axis, strength * share)
    elif e.kind == "vortex":
        turn = _cross(axis, vec)
        direction = turn / np.maximum(np.linalg.norm(turn, axis=1), 1e-9)[:, None]
    else:  # turbulence: noise fixed to the field
        direction = turbulence(turbulence_offsets(e, points))
    return direction * (strength * share)[:, None]


def _plane_vortex(e: Effector, points: np.ndarray, axis: np.ndarray, effect: np.ndarray) -> np.ndarray:
    """A Vortex of Plane shape (Blender's default for it): Blender's "new vortex", a turn around
    the axis plus a pull towards it in the ratio of the effect (strength times falloff): at
    strength 1 the air moves 45 degrees inwards of the turn, as Blender's particles do."""
    vec = points - e.matrix[:3, 3]
    turn = _cross(axis, vec)
    size = np.maximum(np.linalg.norm(turn, axis=1), 1e-9)[:, None]
    turn /= size
    inward = _cross(axis, turn)  # (axis x (axis x r): towards the axis)
    return turn * effect[:, None] + inward * (effect * effect)[:, None]  # (the pull is inwards either way)


def _cross(axis: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """(m, 3) ``axis`` (3,) x each row of ``vec`` (m, 3) (np.cross's products, without its
    broadcasting)."""
    ax, ay, az = (float(a) for a in axis)
    x, y, z = vec[:, 0], vec[:, 1], vec[:, 2]
    return np.column_stack([ay * z - az * y, az * x - ax * z, ax * y - ay * x])


class ForcedWind:
    """A wind field (``sample_layout``) plus the effectors' pushes at the cells, at half the
    grass's height above the ground. Everything else is the wind field's."""

    def __init__(self, wind, effectors):
        self.wind = wind
        self.effectors = effectors
        self.turbulence = _Kept(getattr(effectors, "turbulence", None) or turbulence_vector)
        self._kept = None

    def __getattr__(self, name):
        return getattr(self.wind, name)

    def sample_layout(self, t: float, layout) -> np.ndarray:
        out = np.array(self.wind.sample_layout(t, layout), dtype=np.float32)
        if layout.n_cells:
            self._push(t, self._points(layout), out)
        return out

    def sample_points(self, t: float, points: np.ndarray) -> np.ndarray:
        """The wind and the effectors' pushes at ``points`` (m, 3) (``wind_map``): (m, 2) float32."""
        points = np.asarray(points, dtype=np.float64)
        out = np.array(self.wind.sample(t, points[:, :2]), dtype=np.float32)
        if len(points):
            self._push(t, points, out)
        return out

    def _push(self, t: float, points: np.ndarray, out: np.ndarray) -> None:
        """``out`` (m, 2) plus the horizontal push of every effector active at ``t`` at ``points``."""
        for e in self.effectors.at(t):
            reach = _reach(e)
            if reach is None:
                out += force(e, points, t, self.turbulence)[:, :2].astype(np.float32)
                continue
            near = _within(points, e.matrix[:3, 3], reach)  # only these points can feel it
            if len(near):
                out[near] += force(e, points[near], t, self.turbulence)[:, :2].astype(np.float32)

    def _points(self, layout) -> np.ndarray:
        """The cells' centres at half the grass's height (kept for the layout)."""
        kept = self._kept
        if kept is None or kept[0] is not layout:
            points = np.column_stack([layout.cell_center, layout.cell_ground + 0.5 * layout.cell_length])
            kept = self._kept = (layout, points.astype(np.float64))
        return kept[1]


class _Kept:
    """A turbulence noise function that keeps its last few answers: a still Turbulence is read at
    the same cells every step (the noise is a fixed field; Blender's is read a point at a time)."""

    KEEP = 4

    def __init__(self, noise):
        self.noise = noise
        self._answers: dict[bytes, np.ndarray] = {}

    def __call__(self, q: np.ndarray) -> np.ndarray:
        q = np.ascontiguousarray(q, np.float64)
        key = hashlib.sha1(q.tobytes()).digest()
        found = self._answers.get(key)
        if found is None:
            found = self.noise(q)
            if len(self._answers) >= self.KEEP:
                self._answers.pop(next(iter(self._answers)))
            self._answers[key] = found
        return found


def _within(points: np.ndarray, centre: np.ndarray, reach: float) -> np.ndarray:
    """Indices of the ``points`` within ``reach`` of ``centre`` horizontally (an effector adds
    nothing beyond its maximum distance)."""
    x, y = points[:, 0] - centre[0], points[:, 1] - centre[1]
    box = np.flatnonzero((np.abs(x) <= reach) & (np.abs(y) <= reach))
    return box[x[box] * x[box] + y[box] * y[box] <= reach * reach]


def _reach(e: Effector) -> float | None:
    """How far from its centre an effector of point shape and sphere falloff acts (None: any distance)."""
    if e.use_max and e.shape == "point" and e.falloff_type == "sphere":
        return e.max_distance
    return None


MAX_EFFECTORS = 32  # force fields acting at once: each is computed at every cell it reaches, every frame


def check_count(effectors) -> None:
    """Refuse more than MAX_EFFECTORS force fields at an instant (200 took 4 s a frame), naming
    the setting (Blender: the Force Fields collection)."""
    parts = getattr(effectors, "sources", None) or ([effectors] if effectors is not None else [])
    most, sampled = 0, False
    for part in parts:
        samples = getattr(part, "samples", None)
        sampled = sampled or samples is not None
        counts = [len(s) for s in samples] if samples is not None else [len(getattr(part, "effectors", ()) or ())]
        most += max(counts, default=0)
    if most > MAX_EFFECTORS:
        raise ParameterError("effector_collection" if sampled else "interaction.effectors",
                             f"{most} force fields act at once; valid: at most {MAX_EFFECTORS} (each is computed "
                             "at every cell it reaches, every frame: join them, or give them a maximum distance)")
