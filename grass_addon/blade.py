"""One blade at rest: stiffness along the blade and the shape gravity gives it (paper III.A, eqs 1-6).

Joints are numbered from the root: joint ``i`` (0-based) is the bottom of segment ``i`` and lies
at distance ``L = l_length * i`` from the root. Angles are in radians; ``tilt`` is a segment's
angle from the vertical.
"""

from __future__ import annotations

import numpy as np

GRAVITY = 9.81  # g of eq 2, m/s^2
# mu of eq 1 is the stiffness of a joint of a blade drawn with this many segments (the paper's
# experiments use 4-6). With n segments a joint stands for REFERENCE_SEGMENTS / n of such a joint's
# length of blade, so its stiffness is mu * n / REFERENCE_SEGMENTS (springs in series): the joint
# angles then add up to the same shape whatever n, as a bending stiffness EI(s) = mu(s) l_ref would.
REFERENCE_SEGMENTS = 5
# The ground stops a blade: no segment tilts further from the vertical than this (flat ground);
# a hair less than lying flat, so a blade pressed down lies just above the ground.
GROUND_TILT = 0.5 * np.pi - 0.03


# --------------------------------------------------------------------------------------------
# The strip: a blade is drawn as a strip of n rigid segments, widest at its root


def width_at(tip_width: float, t) -> np.ndarray:
    """The strip's width at fractions ``t`` of the blade's length (0 root .. 1 tip), as a
    fraction of its width at the root: it tapers linearly to ``blade.tip_width`` at the tip."""
    return 1.0 - (1.0 - float(tip_width)) * np.asarray(t, dtype=np.float64)


def joint_widths(tip_width: float, segments: int) -> np.ndarray:
    """``width_at`` the n + 1 joints (t = j / n), float64."""
    return 1.0 - (1.0 - float(tip_width)) * np.arange(segments + 1) / segments


def segment_widths(tip_width: float, segments: int) -> np.ndarray:
    """``width_at`` the middles of the n segments (t = (j + 1/2) / n), float64: the width a
    segment shows the wind (eq 16) and a ray."""
    return 1.0 - (1.0 - float(tip_width)) * (np.arange(segments) + 0.5) / segments


def mean_width(tip_width: float) -> float:
    """The strip's area over (root width x length): the mean of its linear taper."""
    return 0.5 * (1.0 + float(tip_width))


# --------------------------------------------------------------------------------------------
# Stiffness and the rest shape (eqs 1-6)


def joint_stiffness(root_stiffness: np.ndarray, segment_length: np.ndarray, segments: int,
                    offset: float) -> np.ndarray:
    """mu_i^base of every joint, shape (..., n).

    Eq 5 (eq 1 at L = l_length * i): mu_i = mu_root / (l_length * i + x). The root is the
    stiffest joint; stiffness falls towards the tip. Scaled by n / REFERENCE_SEGMENTS so that a
    blade's shape does not depend on how many segments draw it.
    """
    i = np.arange(segments, dtype=np.float64)
    L = np.asarray(segment_length, dtype=np.float64)[..., None] * i
    per_joint = segments / REFERENCE_SEGMENTS
    return (np.asarray(root_stiffness, dtype=np.float64)[..., None] * per_joint / (L + offset)).astype(np.float32)


def segment_weight(density: float, segment_length: np.ndarray) -> np.ndarray:
    """f^G of eq 2: the weight of one segment, rho_grass * l_length * g (rho is a linear density)."""
    return (density * np.asarray(segment_length, dtype=np.float64) * GRAVITY).astype(np.float32)


def rest_angles(inclination: np.ndarray, segment_length: np.ndarray, stiffness: np.ndarray,
                density: float, iterations: int = 40) -> np.ndarray:
    """theta_i^base of eq 6 for every joint of every blade, shape (B, n), radians.

    Eq 6 reads theta = M^G * mu; eq 21 divides a torque by the same mu to get an angle, and mu is
    a stiffness (eq 1), so the physically sound reading, used here, is theta = M^G / mu.

    Eq 4 takes the lever of the weight above joint i as (n-i)*l_length along T, the blade's
    direction; with T upright the cross product vanishes, so the paper starts from a random
    inclination alpha (Fig. 5). We use the exact lever of a segmented cantilever: the horizontal
    distance from joint i to the centre of each segment above it (eqs 3-4 summed segment by
    segment). As the lever depends on the bent shape, the statics are solved by under-relaxed
    fixed-point iteration; a blade that droops past the horizontal loses lever, so it converges.

    inclination: (B,) alpha, the random initial tilt of the blade's first segment.
    segment_length: (B,) l_length. stiffness: (B, n) mu_i^base. density: rho_grass in kg/m.
    """
    # Work transposed, (n, B): cumulative sums then run along the short axis over contiguous rows.
    alpha = np.asarray(inclination, dtype=np.float32)[None, :]
    seg = np.asarray(segment_length, dtype=np.float32)[None, :]
    mu = np.asarray(stiffness, dtype=np.float32).T
    weight = segment_weight(density, seg)  # f^G, eq 2
    theta = np.zeros_like(mu)
    tilt = np.repeat(alpha, mu.shape[0], axis=0)  # absolute tilt of every segment
    for _ in range(iterations):
        new, tilt = _relaxed(alpha, seg, mu, weight, theta, tilt)
        if tilt.max(initial=0.0) > GROUND_TILT32:
            new, tilt = _stopped_by_ground(alpha, tilt)
        change = np.abs(new - theta).max(initial=0.0)
        theta = new
        if change < REST_TOLERANCE:
            break
    return np.ascontiguousarray(theta.T, dtype=np.float32)


REST_TOLERANCE = 5e-6  # rad: rest_angles stops when no joint moves more in an iteration (no render shows it)
GROUND_TILT32 = np.float32(GROUND_TILT)


def _relaxed(alpha, seg, mu, weight, theta, tilt) -> tuple[np.ndarray, np.ndarray]:
    """One under-relaxed fixed-point iteration of eqs 2-6 on (n, B) arrays: (joint angles, tilts)
    from the tilts of the last iteration, before the ground stops them."""
    n = mu.shape[0]
    above = np.arange(n, 0, -1, dtype=np.float32)[:, None]  # (n - i): segments at and above joint i (eq 3)
    dx = seg * np.sin(tilt)  # horizontal extent of every segment
    joint_x = _cumsum_rows(dx) - dx  # horizontal position of joint i
    centre_x = joint_x + 0.5 * dx
    # sum over segments j >= i of their centres, by a reversed cumulative sum
    centre_sum = _cumsum_rows(centre_x[::-1])[::-1]
    torque = weight * (centre_sum - above * joint_x)  # M_i^G, eqs 3-4
    target = torque / mu  # eq 6
    new = 0.5 * theta + 0.5 * target
    return new, alpha + _cumsum_rows(new)


def rest_angles_blocks(inclination: np.ndarray, segment_length: np.ndarray, stiffness: np.ndarray,
                       density: float, iterations: int = 40) -> np.ndarray:
    """``rest_angles`` of k blocks of B blades at once: inclination and segment_length (k, B),
    stiffness (k, B, n) -> (k, B, n), each block the bits ``rest_angles`` gives it alone (the
    ground's stop and the end of the iterations are decided block by block). One pass over
    several blocks' rows costs little more than over one block's, and each iteration writes into
    the same arrays (``_Relaxation``): a block's rest shape in less than half the time."""
    k, B = np.shape(inclination)
    alpha = np.asarray(inclination, dtype=np.float32).reshape(1, k * B)
    seg = np.asarray(segment_length, dtype=np.float32).reshape(1, k * B)
    mu = np.ascontiguousarray(np.asarray(stiffness, dtype=np.float32).reshape(k * B, -1).T)
    n = mu.shape[0]
    relax = _Relaxation(alpha, seg, mu, segment_weight(density, seg))
    theta, tilt = np.zeros_like(mu), np.repeat(alpha, n, axis=0)
    new, new_tilt, change = np.empty_like(mu), np.empty_like(mu), np.empty_like(mu)
    going = np.ones(k, bool)  # blocks still iterating

    def per_block(a: np.ndarray) -> np.ndarray:  # (n, k B) -> (k,) the block's largest
        return a.max(axis=0).reshape(k, B).max(axis=1, initial=0.0)

    for _ in range(iterations):
        relax.step(theta, tilt, new, new_tilt)
        grounded = per_block(new_tilt) > GROUND_TILT32
        if grounded.any():
            stopped, stopped_tilt = _stopped_by_ground(alpha, new_tilt)
            columns = np.repeat(grounded, B)
            np.copyto(new, stopped, where=columns)
            np.copyto(new_tilt, stopped_tilt, where=columns)
        np.abs(np.subtract(new, theta, out=change), out=change)
        moved = per_block(change)
        if going.all():
            theta, new, tilt, new_tilt = new, theta, new_tilt, tilt
        else:  # (a block that has stopped keeps its angles)
            columns = np.repeat(going, B)
            np.copyto(theta, new, where=columns)
            np.copyto(tilt, new_tilt, where=columns)
        going &= ~(moved < REST_TOLERANCE)
        if not going.any():
            break
    return np.ascontiguousarray(theta.T, dtype=np.float32).reshape(k, B, n)


class _Relaxation:
    """``_relaxed`` on (n, B) arrays, each operation writing into arrays kept from one iteration
    to the next (the same operations in the same order: the same bits, without allocating a
    dozen arrays an iteration)."""

    def __init__(self, alpha: np.ndarray, seg: np.ndarray, mu: np.ndarray, weight: np.ndarray):
        self.alpha, self.seg, self.mu, self.weight = alpha, seg, mu, weight
        self.above = np.arange(mu.shape[0], 0, -1, dtype=np.float32)[:, None]  # (n - i), eq 3
        self.dx, self.joint_x, self.centre, self.torque = (np.empty_like(mu) for _ in range(4))

    def step(self, theta: np.ndarray, tilt: np.ndarray, new: np.ndarray, new_tilt: np.ndarray) -> None:
        """(joint angles, tilts) into ``new``, ``new_tilt`` from ``theta``, ``tilt``."""
        dx, joint_x, centre, torque = self.dx, self.joint_x, self.centre, self.torque
        np.multiply(self.seg, np.sin(tilt, out=dx), out=dx)  # horizontal extent of every segment
        np.subtract(_cumsum_rows(dx, joint_x), dx, out=joint_x)  # joint i's horizontal position
        np.add(joint_x, np.multiply(0.5, dx, out=centre), out=centre)
        torque[-1] = centre[-1]  # sum over segments j >= i of their centres
        for i in range(len(torque) - 2, -1, -1):
            np.add(torque[i + 1], centre[i], out=torque[i])
        np.subtract(torque, np.multiply(self.above, joint_x, out=joint_x), out=torque)
        np.multiply(self.weight, torque, out=torque)  # M_i^G, eqs 3-4
        np.divide(torque, self.mu, out=torque)  # eq 6
        np.add(np.multiply(0.5, theta, out=new), np.multiply(0.5, torque, out=torque), out=new)
        np.add(self.alpha, _cumsum_rows(new, new_tilt), out=new_tilt)


def _stopped_by_ground(alpha: np.ndarray, tilt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(joint angles, tilts) (n, B) with every absolute tilt held at GROUND_TILT at most.

    Gravity only bends a blade further down (theta >= 0), so the tilts rise root to tip and the
    held ones are the top of the blade."""
    tilt = np.minimum(tilt, np.float32(GROUND_TILT))
    theta = np.empty_like(tilt)
    theta[0] = tilt[0] - alpha[0]
    np.subtract(tilt[1:], tilt[:-1], out=theta[1:])
    return theta, tilt


def _cumsum_rows(a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cumulative sum down the (few) rows of an (n, B) array (into ``out``, not ``a``); much
    faster than np.cumsum(axis=0)."""
    out = np.empty_like(a) if out is None else out
    out[0] = a[0]
    for i in range(1, a.shape[0]):
        np.add(out[i - 1], a[i], out=out[i])
    return out


def tip_height(length: np.ndarray, tilt: np.ndarray, shares: np.ndarray | None = None) -> np.ndarray:
    """Height of each blade's tip above its root: sum over its n segments of (length / n) cos(tilt),
    or of length times each segment's share of it (``shares`` (B, n), meadow.segment_shares)."""
    if shares is None:
        return (length[:, None] / tilt.shape[1] * np.cos(tilt)).sum(axis=1)
    return (length[:, None] * shares * np.cos(tilt)).sum(axis=1)


def rest_tilt(inclination: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Absolute tilt from vertical of each segment at rest: alpha + sum of theta_base up to i."""
    return (np.asarray(inclination, dtype=np.float32)[:, None] + np.cumsum(angles, axis=1)).astype(np.float32)
