"""Grass that reacts to what moves through it: colliders push it aside and trample it (issue #19).

Colliders are sphere sets over time (``Track``): a scene file's ``[[colliders]]`` (a sphere, or a
capsule as spheres along its axis) moving along keyed path points, or, in Blender, the objects of
the field's collider collection sampled from the evaluated scene once per frame (bridge/tracks.py).

What a collider does to a cell is a pure function of the track and the frame, never of frames
shown before, so any frame is still seconds away and farm splits stay pixel-identical:

* **Push** (frame N only): blades near a collider lean away from it, as far as a straight blade
  of the cell's length must lean to clear the sphere (``push_lean``); the wind's bend towards the
  collider is blocked. ``clearance.clear_blades`` then bends any blade still reaching into a
  sphere out of it (roots fixed, lengths kept), so nothing drawn is inside a collider.
* **Trample** (frames N - W .. N, W = interaction.recovery): at each frame a collider's contacts
  press the cells under it by ``a`` (1 where it reaches the ground, 0 where its lowest point is
  above the grass) along its direction of travel. The window's frames are taken in chunks of
  W / CHUNKS_PER_WINDOW frames, a cell's presses in a chunk as one: the strongest, at the last
  frame it was pressed (the grass stays down while a collider is on it). A cell shows
  ``max over chunks of a R(t - s)``, ``R`` the recovery curve: flattened, rising slowly, then
  released into the paper's damped oscillation (eqs 29-32, the cell's own K/M and C/M) so that
  it is back at its wind-only pose when ``interaction.recovery`` has passed. The wind keeps
  acting on trampled grass, weaker while it is flat (``WIND_WHEN_FLAT``).

* **Trail map** (``trail_map``): how flat the trampled cells are, rasterised over the box around
  them, for the far canopy (no cell is simulated there): the held curve of ``R`` and a smooth
  release (``far_recovery``; a canopy pixel stands for many cells, no single oscillation).

Contacts are computed per frame for the cells under each sphere only and kept, merged per chunk,
for the window W, so the work is proportional to the cells the colliders reach (Fan et al. 2015),
a cell counted once per chunk however long a collider stays on it: a field with no collider
does nothing here, a collider outside the window of simulated blocks touches nothing.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .blade import GROUND_TILT
from .clock import Clock
from .errors import ParameterError
from .schema import Params

FLAT_TILT = 1.45  # rad (83 deg): how far a fully trampled blade leans
HOLD = 0.6  # share of interaction.recovery a trampled blade spends rising slowly before its release
HELD_FLAT = 0.5  # how flat it still is at the release
FADE = 0.1  # share of interaction.recovery over which the last of the oscillation is faded out
WIND_WHEN_FLAT = 0.25  # the wind's bend on fully flattened grass, against standing grass
PUSH_MARGIN = 1.1  # the lean clears a sphere this much larger than the collider
LEAN_STEPS = 24  # lean angles tried between 0 and GROUND_TILT (push_lean)
# How the lean of a blade is shared between its joints (mostly at the base: it bends where it is
# weakest under a load from above); the last entry is for every joint above.
JOINT_SHARE = (0.55, 0.25, 0.12, 0.08)
CAPSULE_SPHERES_PER_RADIUS = 2.0  # a capsule is spheres along its axis, this many per radius
STILL_SPEED = 0.05  # m/s: slower colliders press the grass outwards, not along their travel
TRAIL_PIXELS = 256  # the trail map's side: its box is square, at least TRAIL_MARGIN pixels around the trail
TRAIL_MARGIN = 2
# The recovery window's frames are taken in chunks (aligned on frame numbers, so a frame alone gets
# the same), a cell's presses within a chunk as one: its strongest, from the last frame it was
# pressed in (the grass stays down while a collider is on it). A chunk is 1/CHUNKS_PER_WINDOW of
# the window (12 frames at 24 fps for the default 4 s), so a frame's work does not grow with it.
CHUNKS_PER_WINDOW = 8
# Spheres times the recovery window's frames a field's colliders may weigh: a frame shown alone
# (a farm node's first) then takes a few seconds at most (500 colliders with a 600 s recovery: 125 s).
MAX_SPHERE_FRAMES = 150_000


# ------------------------------------------------------------------------------------------------
# Tracks: where the colliders are


@dataclass(frozen=True)
class Spheres:
    """Spheres at one instant: centres (m, 3), radii (m,), horizontal velocities (m, 2) (float64)."""

    centres: np.ndarray
    radii: np.ndarray
    velocity: np.ndarray

    @staticmethod
    def none() -> Spheres:
        return Spheres(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 2)))

    def __len__(self) -> int:
        return len(self.radii)

    @staticmethod
    def join(parts) -> Spheres:
        parts = [p for p in parts if len(p)]
        if not parts:
            return Spheres.none()
        return Spheres(np.concatenate([p.centres for p in parts]), np.concatenate([p.radii for p in parts]),
                       np.concatenate([p.velocity for p in parts]))


def _spheres_per_instant(collider, reach: float = math.inf) -> float:
    """How many spheres a collider has at an instant that can reach ``reach`` metres above the
    ground at z = 0 (on average, for sampled tracks)."""
    if isinstance(collider, PathCollider):
        low = float(collider.positions[:, 2].min()) + collider.offsets[:, 2] - collider.radius
        return float(max(1, int(np.count_nonzero(low < reach))))
    offsets = getattr(collider, "offsets", None)
    if offsets is not None and len(offsets) > 1:
        return float(offsets[-1] - offsets[0]) / (len(offsets) - 1)
    return 1.0


class PathCollider:
    """A scene file's collider: a sphere (or a vertical capsule: ``length`` between its end
    spheres' centres, ``position`` its middle) moving through keyed ``(time, position)`` points,
    in straight lines between them and held before the first and after the last."""

    def __init__(self, shape: str, radius: float, length: float, times, positions):
        self.times = np.asarray(times, np.float64)
        self.positions = np.asarray(positions, np.float64).reshape(-1, 3)
        self.radius = float(radius)
        if shape == "capsule" and length > 0.0:
            count = max(2, int(math.ceil(length / self.radius * CAPSULE_SPHERES_PER_RADIUS)) + 1)
            z = np.linspace(-0.5 * length, 0.5 * length, count)
        else:
            z = np.zeros(1)
        self.offsets = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)

    def at(self, t: float) -> Spheres:
        times, pos = self.times, self.positions
        centre = np.array([np.interp(t, times, pos[:, i]) for i in range(3)])
        k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2))
        span = times[k + 1] - times[k]
        inside = times[0] <= t < times[-1]
        velocity = (pos[k + 1, :2] - pos[k, :2]) / span if inside and span > 0 else np.zeros(2)
        m = len(self.offsets)
        return Spheres(centre + self.offsets, np.full(m, self.radius), np.tile(velocity, (m, 1)))


class SampledTrack:
    """Sphere sets sampled at given times (Blender's colliders, once per frame): the set of the
    sample nearest to ``t``. ``times`` (K,) ascending; ``offsets`` (K + 1,) the rows of each sample
    in ``centres`` (S, 3), ``radii`` (S,), ``velocity`` (S, 2)."""

    def __init__(self, times, offsets, centres, radii, velocity):
        self.times = np.asarray(times, np.float64)
        self.offsets = np.asarray(offsets, np.int64)
        self.centres = np.asarray(centres, np.float64).reshape(-1, 3)
        self.radii = np.asarray(radii, np.float64)
        self.velocity = np.asarray(velocity, np.float64).reshape(-1, 2)

    def at(self, t: float) -> Spheres:
        if not len(self.times):
            return Spheres.none()
        k = nearest_sample(self.times, t)
        a, b = self.offsets[k], self.offsets[k + 1]
        return Spheres(self.centres[a:b], self.radii[a:b], self.velocity[a:b])


def nearest_sample(times: np.ndarray, t: float) -> int:
    """Index of the sample time (ascending ``times``, not empty) nearest to ``t`` (the earlier on a tie)."""
    k = int(np.clip(np.searchsorted(times, t), 0, len(times) - 1))
    if k > 0 and t - times[k - 1] <= times[k] - t:
        k -= 1
    return k


def check_work(colliders, params: Params, top: float) -> None:
    """Refuse, before anything is computed, colliders whose remembered contacts a frame alone
    would take too long to weigh: spheres at an instant times the recovery's frames (``top``: the
    grass's height, m)."""
    fps = Clock.of(params).rate
    recovery = float(params.interaction.recovery)
    window = int(math.ceil(recovery * fps))
    reach = 1.5 * max(float(top), 1e-3) + float(params.interaction.tolerance) + 1.0
    spheres = sum(_spheres_per_instant(c, reach) for c in colliders)
    work = spheres * window
    if work > MAX_SPHERE_FRAMES:
        longest = max(0.1, math.floor(MAX_SPHERE_FRAMES / max(spheres, 1) / fps * 10) / 10)
        raise ParameterError(
            "interaction.recovery", f"{spheres:g} collider spheres remembered for {recovery:g} s weigh "
            f"{work:,.0f} contacts for a frame shown alone; valid: interaction.recovery up to {longest:g} s "
            "with these colliders (or fewer colliders)")


def check_scene(params: Params) -> None:
    """A scene file's colliders checked as the engine will (``check_work``), before a scene is
    built for them (render_field.py built 10,000 for minutes before the engine refused them)."""
    colliders = colliders_from_params(params)
    if colliders:
        check_work(colliders, params, max(float(sp["length"]) for sp in params.species()))


def colliders_from_params(params: Params) -> list[PathCollider]:
    """The ``[[colliders]]`` of a scene file (validated by the schema)."""
    out = []
    for row in params.interaction.colliders:
        path = row["path"]
        out.append(PathCollider(row["shape"], row["radius"], row["length"], [p["time"] for p in path],
                                [p["position"] for p in path]))
    return out


# ------------------------------------------------------------------------------------------------
# The recovery curve


def recovery_curve(tau: np.ndarray, recovery: float, omega2: np.ndarray, damping: np.ndarray) -> np.ndarray:
    """R(tau): how flat a cell pressed ``tau`` seconds ago still is (1 pressed, 0 recovered).

    Held: 1 - (1 - HELD_FLAT) (tau / h)^2 up to h = HOLD * recovery (the stems slowly straighten);
    then released: HELD_FLAT g(tau - h), g the free damped oscillation of eqs 29-32 from rest at
    1 (K/M = ``omega2``, C/M = ``damping``, the cell's base joint), faded out over the last FADE
    of the recovery; 0 from ``recovery`` on."""
    tau = np.asarray(tau, np.float64)
    h = HOLD * recovery
    held = _held(tau, h)
    x = np.maximum(tau - h, 0.0)
    a = 0.5 * np.asarray(damping, np.float64)
    w2 = np.asarray(omega2, np.float64)
    wd = np.sqrt(np.maximum(w2 - a * a, 0.0))
    under = wd > 1e-6
    safe = np.where(under, wd, 1.0)
    g_under = np.exp(-a * x) * (np.cos(safe * x) + a / safe * np.sin(safe * x))
    slow = np.sqrt(np.maximum(w2, 0.0))  # overdamped: the critically damped curve of the slower rate
    g_over = np.exp(-slow * x) * (1.0 + slow * x)
    g = np.where(under, g_under, g_over)
    u = np.clip((tau - (1.0 - FADE) * recovery) / (FADE * recovery), 0.0, 1.0)
    fade = 1.0 - u * u * (3.0 - 2.0 * u)
    released = HELD_FLAT * g * fade
    out = np.where(tau < h, held, released)
    return np.where((tau >= 0.0) & (tau < recovery), out, 0.0)


def _held(tau: np.ndarray, h: float) -> np.ndarray:
    """The held part of R: 1 - (1 - HELD_FLAT) (tau / h)^2 up to h (then HELD_FLAT)."""
    return 1.0 - (1.0 - HELD_FLAT) * np.square(np.clip(tau / max(h, 1e-9), 0.0, 1.0))


def far_recovery(tau: np.ndarray, recovery: float) -> np.ndarray:
    """How flat a trail seen from afar still is ``tau`` seconds after the press: ``recovery_curve``'s
    held part, then HELD_FLAT easing smoothly to 0 at ``recovery`` (no oscillation: a far pixel
    averages many cells, which swing out of step)."""
    tau = np.asarray(tau, np.float64)
    h = HOLD * recovery
    held = _held(tau, h)
    u = np.clip((tau - h) / max(recovery - h, 1e-9), 0.0, 1.0)
    out = np.where(tau < h, held, HELD_FLAT * (1.0 - u * u * (3.0 - 2.0 * u)))
    return np.where((tau >= 0.0) & (tau < recovery), out, 0.0)


@dataclass(frozen=True)
class TrailMap:
    """How flat the grass is around the trails of one frame: ``flat`` (TRAIL_PIXELS, TRAIL_PIXELS)
    float32 in [0, 1], row 0 at y0, over the square ``extent`` (x0, y0, x1, y1) in the field's
    frame (m)."""

    extent: tuple[float, float, float, float]
    flat: np.ndarray


# ------------------------------------------------------------------------------------------------
# Contacts: the cells under the spheres at one instant


@dataclass(frozen=True)
class Contacts:
    """Cells pressed at one frame, or over a span of frames (``merge``): global cell ids (m,),
    ascending; per cell its strongest press (m,) in (0, 1], and the time (m,) and direction
    (m, 2) of the last frame it was pressed in; ``box``: (first column, last column, first row,
    last row) of the cells (ids are row-major)."""

    cells: np.ndarray
    press: np.ndarray
    direction: np.ndarray
    when: np.ndarray
    box: tuple = (0, -1, 0, -1)

    @staticmethod
    def none() -> Contacts:
        return Contacts(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2)), np.zeros(0))

    def __len__(self) -> int:
        return len(self.cells)

    @staticmethod
    def merge(parts) -> Contacts:
        """The contacts of the frames of ``parts`` (contacts of frames or spans that do not
        overlap) together: per cell the strongest press, the time and direction of its last
        one. Merging is exact (a maximum and a choice), so any grouping gives the same."""
        parts = [p for p in parts if len(p)]
        if len(parts) < 2:
            return parts[0] if parts else Contacts.none()
        cells = np.concatenate([p.cells for p in parts])
        when = np.concatenate([p.when for p in parts])
        order = np.lexsort((when, cells))
        cells, when = cells[order], when[order]
        start = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]])
        last = np.r_[start[1:], len(cells)] - 1
        press = np.maximum.reduceat(np.concatenate([p.press for p in parts])[order], start)
        direction = np.concatenate([p.direction for p in parts])[order[last]]
        boxes = np.array([p.box for p in parts])
        box = (int(boxes[:, 0].min()), int(boxes[:, 1].max()), int(boxes[:, 2].min()), int(boxes[:, 3].max()))
        return Contacts(cells[start], press, direction, when[last], box)


def _cells_around(grid, spheres: Spheres, reach: np.ndarray):
    """(sphere index, global cell id, cell centre (., 2)) of the field's cells whose centres lie
    within ``reach`` (m,) of each sphere's centre, horizontally. A sphere wider than a few hundred
    cells looks only at the field's cells under it (the work follows what it touches)."""
    cs = grid.cell_size
    origin = np.asarray(grid.origin, np.float64)
    k = int(math.ceil(float(reach.max()) / cs)) + 1
    if (2 * k + 1) ** 2 * len(spheres) > WIDE_CELLS:
        return _cells_under_wide(grid, spheres, reach)
    offsets = np.arange(-k, k + 1)
    grid_x, grid_y = np.meshgrid(offsets, offsets)
    ox, oy = grid_x.ravel(), grid_y.ravel()
    ix0 = np.floor((spheres.centres[:, 0] - origin[0]) / cs).astype(np.int64)
    iy0 = np.floor((spheres.centres[:, 1] - origin[1]) / cs).astype(np.int64)
    ix = ix0[:, None] + ox[None, :]
    iy = iy0[:, None] + oy[None, :]
    cx = origin[0] + (ix + 0.5) * cs
    cy = origin[1] + (iy + 0.5) * cs
    d2 = (cx - spheres.centres[:, 0:1]) ** 2 + (cy - spheres.centres[:, 1:2]) ** 2
    keep = (d2 <= (reach[:, None] ** 2)) & (ix >= 0) & (iy >= 0) & (ix < grid.cells_x) & (iy < grid.cells_y)
    s, j = np.nonzero(keep)
    ids = iy[s, j] * grid.cells_x + ix[s, j]
    return s, ids, np.stack([cx[s, j], cy[s, j]], axis=1)


WIDE_CELLS = 1 << 20  # candidate cells above which spheres are looked at one by one, clipped to the field


def _cells_under_wide(grid, spheres: Spheres, reach: np.ndarray):
    """``_cells_around`` a sphere at a time, each over the part of the field's grid its reach
    covers (a collider of 100 m radius over a 6 m field looks at the field's cells, not 4 million)."""
    cs, origin = grid.cell_size, np.asarray(grid.origin, np.float64)
    found_s, found_ids, found_xy = [], [], []
    for s in range(len(spheres)):
        c, r = spheres.centres[s, :2], float(reach[s])
        lo = np.maximum(np.floor((c - r - origin) / cs).astype(np.int64), 0)
        hi = np.minimum(np.floor((c + r - origin) / cs).astype(np.int64), [grid.cells_x - 1, grid.cells_y - 1])
        if (hi < lo).any():
            continue
        iy, ix = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
        ix, iy = ix.ravel(), iy.ravel()
        xy = np.column_stack([origin[0] + (ix + 0.5) * cs, origin[1] + (iy + 0.5) * cs])
        keep = ((xy - c) ** 2).sum(axis=1) <= r * r
        found_s.append(np.full(int(keep.sum()), s, np.int64))
        found_ids.append(iy[keep] * grid.cells_x + ix[keep])
        found_xy.append(xy[keep])
    if not found_s:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2))
    return np.concatenate(found_s), np.concatenate(found_ids), np.concatenate(found_xy)


def contacts(grid, spheres: Spheres, ground, top: float, t: float = 0.0) -> Contacts:
    """The cells ``spheres`` press at time ``t``: a cell at horizontal distance d < r from a
    sphere's centre is pressed by ``a = clip((top - z_low) / top, 0, 1)``, ``z_low`` the height
    of the sphere's lowest point over the cell above the ground (``ground(xy) -> z``) and ``top``
    the grass's height; along the sphere's horizontal travel, or outwards when it stands still."""
    if not len(spheres):
        return Contacts.none()
    s, ids, xy = _cells_around(grid, spheres, spheres.radii)
    if not len(ids):
        return Contacts.none()
    c = spheres.centres[s]
    r = spheres.radii[s]
    rel = xy - c[:, :2]
    d2 = np.sum(rel * rel, axis=1)
    z_low = c[:, 2] - np.sqrt(np.maximum(r * r - d2, 0.0)) - ground(xy)
    press = np.clip((top - z_low) / top, 0.0, 1.0)
    v = spheres.velocity[s]
    speed = np.hypot(v[:, 0], v[:, 1])
    moving = speed > STILL_SPEED
    out = np.where(moving[:, None], v / np.maximum(speed, 1e-9)[:, None],
                   rel / np.maximum(np.sqrt(d2), 1e-9)[:, None])
    keep = press > 0.0
    # one contact per cell: the strongest press
    order = np.lexsort((press[keep], ids[keep]))
    cells, a, direction = ids[keep][order], press[keep][order], out[keep][order]
    last = np.r_[cells[1:] != cells[:-1], True] if len(cells) else np.zeros(0, bool)
    cells = cells[last]
    if not len(cells):
        return Contacts.none()
    columns = cells % grid.cells_x
    box = (int(columns.min()), int(columns.max()), int(cells[0] // grid.cells_x), int(cells[-1] // grid.cells_x))
    return Contacts(cells, a[last], direction[last], np.full(len(cells), float(t)), box)


# ------------------------------------------------------------------------------------------------
# Push: the lean that clears a sphere


def push_lean(root: np.ndarray, length: np.ndarray, centre: np.ndarray, radius: np.ndarray):
    """(angle (m,), direction (m, 2)): how far a straight blade of ``length`` rooted at ``root``
    (m, 3) must lean away from the sphere (``centre`` (m, 3), ``radius`` (m,)) horizontally for
    its whole length to clear it (0 when it stands clear, GROUND_TILT when nothing clears)."""
    rel = root[:, :2] - centre[:, :2]
    d = np.hypot(rel[:, 0], rel[:, 1])
    direction = np.where(d[:, None] > 1e-9, rel / np.maximum(d, 1e-9)[:, None], np.array([1.0, 0.0]))
    angles = np.linspace(0.0, GROUND_TILT, LEAN_STEPS + 1)
    sin, cos = np.sin(angles)[None, :], np.cos(angles)[None, :]
    # the blade's axis in the vertical plane through the sphere's centre: (d + s sin, z0 + s cos)
    p = np.stack([-d, centre[:, 2] - root[:, 2]], axis=1)  # the centre in (away, up) coordinates
    along = np.clip(p[:, 0:1] * sin + p[:, 1:2] * cos, 0.0, length[:, None])
    gx, gz = p[:, 0:1] - along * sin, p[:, 1:2] - along * cos
    clear = gx * gx + gz * gz >= (radius[:, None] * PUSH_MARGIN) ** 2
    first = np.where(clear.any(axis=1), clear.argmax(axis=1), LEAN_STEPS)
    return angles[first], direction


# ------------------------------------------------------------------------------------------------
# The overlay on a frame's bend


def joint_shares(segments: int) -> np.ndarray:
    """(n,) how a blade's lean is shared between its joints (sums to 1)."""
    share = np.array([JOINT_SHARE[min(j, len(JOINT_SHARE) - 1)] for j in range(segments)], np.float64)
    if segments > len(JOINT_SHARE) - 1:
        share[len(JOINT_SHARE) - 1:] = JOINT_SHARE[-1] / (segments - len(JOINT_SHARE) + 1)
    return share / share.sum()


class Interaction:
    """The colliders of a field and their effect on the cells of a frame.

    ``colliders``: objects with ``at(t) -> Spheres``; ``grid``: the field's ``FieldGrid``;
    ``ground(xy) -> z``; ``top``: the grass's height (m)."""

    def __init__(self, colliders, params: Params, grid, ground, top: float):
        self.colliders = list(colliders)
        self.params = params
        self.recovery = float(params.interaction.recovery)
        self.tolerance = float(params.interaction.tolerance)
        self.grid = grid
        self.ground = ground
        self.top = max(float(top), 1e-3)
        self.clock = Clock.of(params)
        self.fps = self.clock.rate
        self.window = int(math.ceil(self.recovery * self.fps))
        self.chunk = max(1, self.window // CHUNKS_PER_WINDOW)
        check_work(self.colliders, params, self.top)
        self._contacts: OrderedDict[int, Contacts] = OrderedDict()
        self._window: tuple | None = None  # (layout, WindowCells) of the last layout seen
        self._spheres_at: tuple | None = None  # (t, Spheres) of the last instant asked
        self._chunks: OrderedDict[int, Contacts] = OrderedDict()  # whole chunks (recent)
        self._growing: OrderedDict[tuple, Contacts] = OrderedDict()  # (chunk, frame) -> its frames up to frame
        self._local: OrderedDict[int, tuple] = OrderedDict()  # chunk -> its contacts on the window's cells
        self.work = 0  # cells overlaid so far (a measure of work: proportional to the cells reached)

    def time(self, frame: int) -> float:
        return self.clock.seconds(frame)

    def spheres(self, t: float) -> Spheres:
        """The colliders' spheres at time ``t`` that can reach the field (within their radius, the
        push's margin and a blade's length of its rectangle; the last instant asked is kept: a
        frame asks for it three times)."""
        if self._spheres_at is None or self._spheres_at[0] != t:
            every = Spheres.join(c.at(t) for c in self.colliders)
            margin = every.radii * PUSH_MARGIN + self.tolerance + 1.5 * self.top + self.grid.cell_size
            x0, y0 = np.asarray(self.grid.origin, np.float64)
            x1, y1 = x0 + self.grid.size[0], y0 + self.grid.size[1]
            c = every.centres
            near = ((c[:, 0] > x0 - margin) & (c[:, 0] < x1 + margin) & (c[:, 1] > y0 - margin)
                    & (c[:, 1] < y1 + margin)) if len(every) else np.zeros(0, bool)
            if near.any():  # and not above the grass (the top of a tall capsule)
                floor = np.asarray(self.ground(c[near, :2]), np.float64)
                near[near] = c[near, 2] - every.radii[near] < floor + margin[near]
            if not near.all():
                every = Spheres(c[near], every.radii[near], every.velocity[near])
            self._spheres_at = (t, every)
        return self._spheres_at[1]

    def contacts(self, frame: int) -> Contacts:
        """The cells pressed at ``frame`` (the last few kept)."""
        found = self._contacts.get(frame)
        if found is None:
            t = self.time(frame)
            found = contacts(self.grid, self.spheres(t), self.ground, self.top, t)
            self._contacts[frame] = found
            while len(self._contacts) > 8:
                self._contacts.popitem(last=False)
        return found

    def trample(self, frame: int, window: WindowCells, omega2: np.ndarray, damping: np.ndarray):
        """(local cell index (m,), flatness (m,), direction (m, 2)) of the window's trampled cells
        at ``frame``: per cell the strongest press of each chunk (``recent``) times the recovery
        curve from its last frame, the largest over the chunks."""
        parts = self.recent(frame)
        if not parts:
            return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2))
        mine = [self._in_window(k, part, window) for k, part in parts]  # (local, press, direction, when)
        local, press, direction, when = (np.concatenate([m[i] for m in mine]) for i in range(4))
        value = press * recovery_curve(self.time(frame) - when, self.recovery, omega2[local], damping[local])
        keep = value > 1e-4
        local, value, direction = local[keep], value[keep], direction[keep]
        # per cell the strongest (the last one of equal strength), by a maximum over the window's
        # cells (scratch kept per window, cleared after use): no sort of the contacts
        best, heading = window.scratch()
        np.maximum.at(best, local, value)
        winner = value == best[local]
        heading[local[winner]] = direction[winner]
        cells = np.unique(local)  # the cells set above (not a scan of the window's cells)
        out = cells, best[cells].copy(), heading[cells].copy()
        best[cells] = 0.0
        return out

    def flatness(self, frame: int, layout, omega2: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """(n_cells,) how flat the window's cells are trampled at ``frame`` (``trample``), 0..1."""
        if self._window is None or self._window[0] is not layout:
            self._window = (layout, WindowCells(layout, self.grid))
        local, flat, _ = self.trample(frame, self._window[1], omega2, damping)
        out = np.zeros(layout.n_cells)
        out[local] = flat
        return out

    def trail_map(self, frame: int, eyes=(), hidden_within: float = 0.0) -> TrailMap | None:
        """The trails of the recovery window before ``frame`` as a map for the far canopy, None
        when no cell is trampled: per cell the strongest press of each chunk (``recent``) times
        ``far_recovery`` from its last frame, each pixel the flattest of its cells. Chunks whose
        cells all lie within ``hidden_within`` of one of the ``eyes`` (positions, the field's
        frame), where the canopy is not drawn (the LOD's card_near), are left out: the map costs
        only where it can be seen."""
        parts = [part for _, part in self.recent(frame)]
        if len(eyes) and parts:
            seen = ~self._hidden([part.box for part in parts], eyes, hidden_within)
            parts = [part for part, keep in zip(parts, seen) if keep]
        if not parts:
            return None
        when = np.concatenate([part.when for part in parts])
        cells = np.concatenate([part.cells for part in parts])
        flat = np.concatenate([part.press for part in parts]) * far_recovery(self.time(frame) - when, self.recovery)
        keep = flat > 1e-3
        if not keep.any():
            return None
        cells, flat = cells[keep], flat[keep]
        cs, origin = self.grid.cell_size, np.asarray(self.grid.origin, np.float64)
        x = origin[0] + (cells % self.grid.cells_x + 0.5) * cs
        y = origin[1] + (cells // self.grid.cells_x + 0.5) * cs
        side = max(float(x.max() - x.min()), float(y.max() - y.min())) + cs
        pixel = max(side / (TRAIL_PIXELS - 2 * TRAIL_MARGIN), cs)
        x0 = 0.5 * (x.max() + x.min()) - 0.5 * TRAIL_PIXELS * pixel
        y0 = 0.5 * (y.max() + y.min()) - 0.5 * TRAIL_PIXELS * pixel
        image = np.zeros(TRAIL_PIXELS * TRAIL_PIXELS, np.float32)
        px = np.clip(((x - x0) / pixel).astype(np.int64), 0, TRAIL_PIXELS - 1)
        py = np.clip(((y - y0) / pixel).astype(np.int64), 0, TRAIL_PIXELS - 1)
        np.maximum.at(image, py * TRAIL_PIXELS + px, flat.astype(np.float32))
        size = TRAIL_PIXELS * pixel
        return TrailMap((float(x0), float(y0), float(x0 + size), float(y0 + size)),
                        image.reshape(TRAIL_PIXELS, TRAIL_PIXELS))

    def recent(self, frame: int) -> list[tuple[int, Contacts]]:
        """(chunk, its contacts) of every chunk of ``self.chunk`` frames (aligned on frame
        numbers) that overlaps the recovery window before ``frame``, the last one up to
        ``frame``; none without contacts. Whole chunks are kept while the window lasts."""
        size, out = self.chunk, []
        for k in range((frame - self.window) // size, frame // size + 1):
            end = (k + 1) * size - 1
            if end <= frame:
                part = self._chunks.get(k)
                if part is None:
                    part = self._chunks[k] = self._grown(k, end)
                    while len(self._chunks) > self.window // size + 4:
                        self._chunks.popitem(last=False)
            else:
                part = self._grown(k, frame)
            if len(part):
                out.append((k, part))
        return out

    def _grown(self, k: int, frame: int) -> Contacts:
        """The contacts of chunk ``k``'s frames up to ``frame``: those up to the frame before
        grown by a frame when they are kept (the last few asked for: played frames, motion
        blur's N - 1, N, N + 1), else merged anew (the same contacts either way)."""
        part = self._growing.get((k, frame))
        if part is not None:
            return part
        before = self._growing.get((k, frame - 1))
        if before is not None:
            part = Contacts.merge([before, self.contacts(frame)])
        else:
            part = Contacts.merge(self.contacts(f) for f in range(k * self.chunk, frame + 1))
        self._growing[(k, frame)] = part
        while len(self._growing) > 4:
            self._growing.popitem(last=False)
        return part

    def _hidden(self, boxes, eyes, within: float) -> np.ndarray:
        """(len(boxes),) bool: every cell of each box of cells (first, last column, first, last
        row) lies within ``within`` of one eye (by the box's corners)."""
        cs, origin = self.grid.cell_size, np.asarray(self.grid.origin, np.float64)
        box = np.array(boxes, np.float64)
        x = origin[0] + (box[:, :2] + np.array([0.0, 1.0])) * cs  # (boxes, 2): each box's edges
        y = origin[1] + (box[:, 2:] + np.array([0.0, 1.0])) * cs
        corners = np.stack([np.stack([x[:, i], y[:, j]], axis=1) for i in (0, 1) for j in (0, 1)], axis=1)
        hidden = np.zeros(len(boxes), bool)
        for eye in eyes:
            e = np.asarray(eye, np.float64)
            reach = np.sqrt(np.sum((corners - e[:2]) ** 2, axis=2) + e[2] ** 2).max(axis=1)
            hidden |= reach < within
        return hidden

    def _in_window(self, k: int, part: Contacts, window: WindowCells):
        """(local index, press, direction, when) of chunk ``k``'s contacts on the window's cells
        (kept with the chunk while the window lasts)."""
        memo = self._local.get(k)
        if memo is None or memo[0] is not window or memo[1] is not part:
            inside, local = window.find(part.cells)
            memo = (window, part, local, part.press[inside], part.direction[inside], part.when[inside])
            self._local[k] = memo
            while len(self._local) > self.window // self.chunk + 4:
                self._local.popitem(last=False)
        return memo[2:]

    def push(self, frame: int, layout, window: WindowCells):
        """(local cell index (m,), lean (m,), direction (m, 2)) of the window's cells a collider
        leans aside at ``frame``: the largest lean over the spheres near each cell."""
        spheres = self.spheres(self.time(frame))
        if not len(spheres):
            return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2))
        # a cell whose centre stands clear of a sphere (grown by the margin) needs no lean
        reach = (spheres.radii + self.tolerance) * PUSH_MARGIN
        s, ids, xy = _cells_around(self.grid, spheres, reach)
        found, local = window.find(ids)
        s = s[found]
        if not len(local):
            return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2))
        root = np.column_stack([layout.cell_center[local], layout.cell_ground[local]]).astype(np.float64)
        length = layout.cell_length[local].astype(np.float64) * 1.15 + self.tolerance
        lean, direction = push_lean(root, length, spheres.centres[s], spheres.radii[s] + self.tolerance)
        keep = lean > 0.0
        local, lean, direction = local[keep], lean[keep], direction[keep]
        order = np.lexsort((lean, local))
        local, lean, direction = local[order], lean[order], direction[order]
        last = np.r_[local[1:] != local[:-1], True] if len(local) else np.zeros(0, bool)
        return local[last], lean[last], direction[last]

    def bend(self, frame: int, layout, bend_t: np.ndarray, omega2: np.ndarray, damping: np.ndarray):
        """``bend_t`` (n, 2, C) of the wind alone with the colliders' push and trample at
        ``frame`` (a new array), or None when no collider reaches the window's cells."""
        if self._window is None or self._window[0] is not layout:
            self._window = (layout, WindowCells(layout, self.grid))
        window = self._window[1]
        t_local, flat, t_dir = self.trample(frame, window, omega2, damping)
        p_local, lean, p_dir = self.push(frame, layout, window)
        if not len(t_local) and not len(p_local):
            return None
        touched = np.union1d(t_local, p_local)
        self.work += len(touched)
        n = bend_t.shape[0]
        out = bend_t.copy()
        f = np.zeros(len(touched))
        f[np.searchsorted(touched, t_local)] = flat
        wind = bend_t[:, :, touched].astype(np.float64)  # (n, 2, m)
        wind *= (1.0 - (1.0 - WIND_WHEN_FLAT) * f)[None, None, :]
        lean_vec = np.zeros((len(touched), 2))
        lean_vec[np.searchsorted(touched, t_local)] += (FLAT_TILT * flat)[:, None] * t_dir
        if len(p_local):
            i = np.searchsorted(touched, p_local)
            # the collider blocks the wind's bend towards it
            towards = np.einsum("jcm,mc->jm", wind[:, :, i], p_dir)
            wind[:, :, i] -= np.minimum(towards, 0.0)[:, None, :] * p_dir.T[None, :, :]
            lean_vec[i] += lean[:, None] * p_dir
        size = np.hypot(lean_vec[:, 0], lean_vec[:, 1])
        lean_vec *= (np.minimum(size, GROUND_TILT) / np.maximum(size, 1e-9))[:, None]
        share = joint_shares(n)
        out[:, :, touched] = (wind + share[:, None, None] * lean_vec.T[None, :, :]).astype(np.float32)
        return out


class WindowCells:
    """The global cell id (row-major on the field's grid) of each cell of a layout, and their
    sorted order for lookups (made once per layout)."""

    def __init__(self, layout, grid):
        cs, origin = grid.cell_size, np.asarray(grid.origin, np.float64)
        xy = np.asarray(layout.cell_center, np.float64)
        ix = np.floor((xy[:, 0] - origin[0]) / cs).astype(np.int64)
        iy = np.floor((xy[:, 1] - origin[1]) / cs).astype(np.int64)
        self.ids = iy * grid.cells_x + ix
        self.order = np.argsort(self.ids, kind="stable")
        self.sorted = self.ids[self.order]

    def scratch(self) -> tuple[np.ndarray, np.ndarray]:
        """(C,) zeros and (C, 2) for per-cell reductions (callers leave the first at zero)."""
        if not hasattr(self, "_best"):
            self._best = np.zeros(len(self.ids))
            self._heading = np.zeros((len(self.ids), 2))
        return self._best, self._heading

    def find(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(found (m,) bool, local index of the found ones) of global cell ``ids``."""
        if not len(self.sorted):
            return np.zeros(len(ids), bool), np.zeros(0, np.int64)
        pos = np.minimum(np.searchsorted(self.sorted, ids), len(self.sorted) - 1)
        found = self.sorted[pos] == ids
        return found, self.order[pos[found]]
