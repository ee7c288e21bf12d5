"""Blades bent out of colliders: what is drawn never passes through a collider.

The colliders' push and trample lean the cells first (``interaction.Interaction.bend``); a blade
whose strip still reaches into a collider is then bent out of it here, joint by joint from the root
(follow the leader): each segment keeps its length and turns about the joint below it by the
smallest angle that takes its upper joint out of every sphere and keeps it above the ground; the
segments above keep their directions. So

* roots never move and no blade is stretched (every segment keeps its length exactly);
* no joint goes below the ground;
* all spheres are cleared together: each turn answers the sphere the joint is deepest in, a few
  times over, and a joint still inside one after that takes the nearest of fixed directions
  (``DIRECTIONS``) that is clear of all of them;
* a blade rooted inside a collider (under a ball sunk in the ground) is collapsed onto its root,
  so nothing of it is drawn; so is a blade with a joint that no direction takes out of the spheres
  and the ground (deep in a pile of hundreds of overlapping colliders: it reached 3 cm into one).

A joint keeps its strip's half width from a sphere's surface, so the strip's vertices, not only
its middle line, stay out (within half the tolerance). ``clear_blades`` works on the strips of the
blades near the spheres only; a field without colliders never comes here.
"""

from __future__ import annotations

import numpy as np

ITERATIONS = 6  # turns of one joint against the sphere it is deepest in, before the direction search
GROUND_SLACK = 1e-5  # m: how far below the ground a joint may be left (none to speak of)
PAIR_BUDGET = 1 << 21  # (blade, sphere) distances computed at once when pairing them


def _directions() -> np.ndarray:
    """Unit vectors the search tries: 24 headings at elevations from 10 degrees below the horizon
    to straight up."""
    heading = np.radians(np.arange(24) * 15.0)
    rows = [np.array([[0.0, 0.0, 1.0]])]
    for elevation in np.radians([-10.0, 0.0, 15.0, 30.0, 45.0, 60.0, 75.0]):
        rows.append(np.column_stack([np.cos(heading) * np.cos(elevation), np.sin(heading) * np.cos(elevation),
                                     np.full(heading.size, np.sin(elevation))]))
    return np.concatenate(rows)


DIRECTIONS = _directions()


def pairs(roots: np.ndarray, reach: np.ndarray, centres: np.ndarray, radii: np.ndarray):
    """(blade (P,), sphere (P,)) of the blades whose root lies within the sphere's radius plus the
    blade's ``reach`` of its centre: the only spheres a blade can touch."""
    found_b, found_s = [], []
    step = max(1, PAIR_BUDGET // max(1, len(roots)))
    for s0 in range(0, len(radii), step):
        c, r = centres[s0:s0 + step], radii[s0:s0 + step]
        rel = roots[:, None, :] - c[None, :, :]
        near = np.einsum("bmk,bmk->bm", rel, rel) < (r[None, :] + reach[:, None]) ** 2
        b, s = np.nonzero(near)
        found_b.append(b)
        found_s.append(s + s0)
    return np.concatenate(found_b), np.concatenate(found_s)


def _deepest(gap: np.ndarray, blade: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(smallest gap (count,), the pair index that has it (count,), -1 where none) per blade."""
    order = np.lexsort((gap, blade))
    first = np.r_[True, blade[order][1:] != blade[order][:-1]] if len(order) else np.zeros(0, bool)
    best = np.full(count, np.inf)
    at = np.full(count, -1, np.int64)
    picked = order[first]
    best[blade[picked]] = gap[picked]
    at[blade[picked]] = picked
    return best, at


def _away(prev, u, length, centre, target):
    """``u`` turned about ``prev`` by the smallest angle that puts ``prev + length u`` at least
    ``target`` from ``centre`` (straight away from it where no turn reaches that far)."""
    w = prev - centre
    dist = np.maximum(np.linalg.norm(w, axis=1), 1e-12)
    w /= dist[:, None]
    k = (target ** 2 - length ** 2 - dist ** 2) / (2.0 * length * dist)  # cos of the widest angle to w
    k = np.clip(k, -1.0, 1.0)
    along = np.einsum("ik,ik->i", u, w)
    side = u - along[:, None] * w
    norm = np.linalg.norm(side, axis=1)
    flat = norm < 1e-9  # u points straight at the centre or away: turn it towards the horizontal
    if flat.any():
        alt = np.cross(w[flat], np.array([0.0, 0.0, 1.0]))
        bad = np.linalg.norm(alt, axis=1) < 1e-9
        alt[bad] = np.cross(w[flat][bad], np.array([1.0, 0.0, 0.0]))
        side[flat] = alt
        norm[flat] = np.linalg.norm(alt, axis=1)
    side /= norm[:, None]
    turned = k[:, None] * w + np.sqrt(1.0 - k * k)[:, None] * side
    return np.where((along < k)[:, None], turned, u)


def _lift(prev, u, length, floor):
    """``u`` raised just enough that ``prev + length u`` is at least at height ``floor``."""
    uz = np.clip((floor - prev[:, 2]) / length, -1.0, 1.0)
    h = u[:, :2]
    norm = np.linalg.norm(h, axis=1)
    h = np.where((norm > 1e-9)[:, None], h / np.maximum(norm, 1e-12)[:, None], np.array([1.0, 0.0]))
    out = np.empty_like(u)
    out[:, :2] = h * np.sqrt(1.0 - uz * uz)[:, None]
    out[:, 2] = uz
    return np.where((uz > u[:, 2])[:, None], out, u)


def _around(prev, u, length, centre, target, floor):
    """For a joint the turn away from a sphere put below the ground: ``u`` at the lowest height
    the ground allows, turned about the vertical by the smallest angle that clears the sphere
    (unchanged where no heading at that height clears it: the direction search takes those)."""
    uz = np.clip((floor - prev[:, 2]) / length, -1.0, 1.0)
    rho = np.sqrt(1.0 - uz * uz)
    w = prev - centre
    dist = np.maximum(np.linalg.norm(w, axis=1), 1e-12)
    w /= dist[:, None]
    k = (target ** 2 - length ** 2 - dist ** 2) / (2.0 * length * dist)
    w_xy = np.hypot(w[:, 0], w[:, 1])
    need = (k - uz * w[:, 2]) / np.maximum(rho * w_xy, 1e-12)  # cos of the widest heading from w's
    ok = (need <= 1.0) & (rho > 1e-9) & (w_xy > 1e-9)
    widest = np.arccos(np.clip(need, -1.0, 1.0))
    heading_w = np.arctan2(w[:, 1], w[:, 0])
    off = np.angle(np.exp(1j * (np.arctan2(u[:, 1], u[:, 0]) - heading_w)))  # wrapped to (-pi, pi]
    heading = heading_w + np.clip(off, -widest, widest)
    turned = np.column_stack([rho * np.cos(heading), rho * np.sin(heading), uz])
    return np.where(ok[:, None], turned, u)


class _Joint:
    """One joint of the touched blades: where it stands (``prev + length u``) and how far it is
    from each paired sphere's surface (grown by the strip's half width) and above the ground."""

    def __init__(self, prev, length, need, pb, ps, centres, ground, slack):
        self.prev, self.length, self.need = prev, length, need
        self.pb, self.ps, self.centres, self.ground, self.slack = pb, ps, centres, ground, slack

    def gaps(self, u):
        q = self.prev + self.length[:, None] * u
        rel = q[self.pb] - self.centres[self.ps]
        gap = np.sqrt(np.einsum("pk,pk->p", rel, rel)) - self.need
        floor = self.ground(q[:, :2])
        return gap, floor, q

    def bend(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u clear of every sphere and the ground, bent (k,) bool, still inside a sphere (k,) bool:
        no direction clears it)."""
        count = len(u)
        bent = np.zeros(count, bool)
        for _ in range(ITERATIONS):
            gap, floor, q = self.gaps(u)
            best, at = _deepest(gap, self.pb, count)
            inside = best < -self.slack
            low = q[:, 2] < floor - GROUND_SLACK
            if not inside.any() and not low.any():
                return u, bent, np.zeros(count, bool)
            if inside.any():
                i = np.flatnonzero(inside)
                pair = at[i]
                u[i] = _away(self.prev[i], u[i], self.length[i], self.centres[self.ps[pair]],
                             self.need[pair] + 0.25 * self.slack)
            if low.any():
                i = np.flatnonzero(low)
                u[i] = _lift(self.prev[i], u[i], self.length[i], floor[i] + GROUND_SLACK)
            both = np.flatnonzero(inside & low)  # the sphere presses the joint into the ground
            if len(both):
                pair = at[both]
                u[both] = _around(self.prev[both], u[both], self.length[both], self.centres[self.ps[pair]],
                                  self.need[pair] + 0.25 * self.slack, floor[both] + GROUND_SLACK)
            bent |= inside | low
        gap, floor, q = self.gaps(u)
        best, _ = _deepest(gap, self.pb, count)
        stuck = np.flatnonzero((best < -self.slack) | (q[:, 2] < floor - GROUND_SLACK))
        trapped = np.zeros(count, bool)
        if len(stuck):
            u[stuck] = self._search(stuck, u[stuck])
            bent[stuck] = True
            gap, floor, q = self.gaps(u)
            best, _ = _deepest(gap, self.pb, count)
            # deeper in a sphere than the tolerance, or below the ground
            trapped[stuck] = (best[stuck] < -2.0 * self.slack) | (q[stuck, 2] < floor[stuck] - GROUND_SLACK)
        return u, bent, trapped

    def _search(self, stuck: np.ndarray, u: np.ndarray) -> np.ndarray:
        """For the joints ``stuck`` inside a sphere or the ground after the turns: the direction of
        ``DIRECTIONS`` nearest ``u`` that clears every sphere and the ground (else the clearest)."""
        local = np.full(len(self.length), -1, np.int64)
        local[stuck] = np.arange(len(stuck))
        mine = local[self.pb] >= 0
        pb, ps, need = local[self.pb[mine]], self.ps[mine], self.need[mine]
        dirs = DIRECTIONS
        q = self.prev[stuck][:, None, :] + self.length[stuck][:, None, None] * dirs[None]  # (s, D, 3)
        rel = q[pb] - self.centres[ps][:, None, :]
        gap = np.sqrt(np.einsum("pdk,pdk->pd", rel, rel)) - need[:, None]  # (P, D)
        worst = np.full((len(stuck), len(dirs)), np.inf)
        np.minimum.at(worst, pb, gap)
        floor = self.ground(q[..., :2].reshape(-1, 2)).reshape(len(stuck), len(dirs))
        clear = (worst >= -0.5 * self.slack) & (q[..., 2] >= floor)
        worst = np.minimum(worst, q[..., 2] - floor)
        score = np.where(clear, 2.0 + u @ dirs.T, np.minimum(worst, 0.0))
        return dirs[np.argmax(score, axis=1)]


def clear_blades(strips: np.ndarray, centres: np.ndarray, radii: np.ndarray, tolerance: float, ground) -> int:
    """Bend the blades of ``strips`` (b, n + 1, 2, 3) float32, each joint's [left, right] vertices,
    in place, out of the spheres (``centres`` (m, 3), ``radii`` (m,)); ``ground(xy (k, 2)) -> z
    (k,)``. Returns how many blades were bent or collapsed."""
    if not len(strips) or not len(radii):
        return 0
    joints = strips.mean(axis=2, dtype=np.float64)  # (b, n + 1, 3): each joint's middle
    half = 0.5 * np.linalg.norm((strips[:, :, 1] - strips[:, :, 0]).astype(np.float64), axis=-1)
    seg = np.diff(joints, axis=1)  # (b, n, 3): the segments, kept as they are above a turned one
    length = np.linalg.norm(seg, axis=-1)
    reach = length.sum(axis=1) + half.max(axis=1) + tolerance
    pb, ps = pairs(joints[:, 0], reach, centres, radii)
    live = length.sum(axis=1) > 1e-6  # blades LOD hides are collapsed already
    pb, ps = pb[live[pb]], ps[live[pb]]
    if not len(pb):
        return 0
    root = strips[pb, 0].astype(np.float64) - centres[ps][:, None, :]  # (P, 2, 3): the root's two vertices
    root_gap = np.sqrt(np.einsum("pvk,pvk->pv", root, root)).min(axis=1) - radii[ps]
    buried = np.unique(pb[root_gap < -tolerance])
    if len(buried):  # rooted inside a collider: nothing of it is drawn
        strips[buried] = joints[buried, 0][:, None, None, :].astype(np.float32)
        keep = ~np.isin(pb, buried)
        pb, ps = pb[keep], ps[keep]
    blades, pb = np.unique(pb, return_inverse=True)
    out = joints[blades].copy()
    seg, length, half = seg[blades], length[blades], half[blades]
    bent = np.zeros(len(blades), bool)
    trapped = np.zeros(len(blades), bool)
    slack = 0.5 * tolerance
    for j in range(1, seg.shape[1] + 1):
        prev = out[:, j - 1]
        span = np.maximum(length[:, j - 1], 1e-12)
        joint = _Joint(prev, span, radii[ps] + half[pb, j], pb, ps, centres, ground, slack)
        u, turned, stuck = joint.bend(seg[:, j - 1] / span[:, None])
        bent |= turned
        trapped |= stuck
        out[:, j] = np.where(turned[:, None], prev + span[:, None] * u, prev + seg[:, j - 1])
    moved = np.flatnonzero(bent & ~trapped)
    if len(moved):
        b = blades[moved]
        offset = strips[b].astype(np.float64) - joints[b][:, :, None, :]
        strips[b] = (out[moved][:, :, None, :] + offset).astype(np.float32)
    hidden = blades[trapped]  # a joint no direction clears: nothing of the blade is drawn
    strips[hidden] = joints[hidden, 0][:, None, None, :].astype(np.float32)
    return len(moved) + len(hidden) + len(buried)
