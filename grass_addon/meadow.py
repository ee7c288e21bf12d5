"""A meadow's variety, decided when a block is made: tussocks, patches, heads and dry tips.

The paper grows every blade at a uniform random place in its cell, of one species mix everywhere:
a freshly sown lawn. A meadow is uneven at every scale, and each of these is a pure function of
(parameters, seed, place), so a block is the same whenever and wherever it is made (blocks.py):

- **Tussocks** (``field.clumping``, ``field.clump_size``): grasses grow in clumps around clump
  centres, one on each cell of a lattice of the clump size, jittered. A blade's root is pulled
  towards the nearest centre by the clumping share (0: where it was drawn, 1: onto the centre), so
  tussocks stand with bare gaps between them; no blade is added or lost, and each blade keeps its
  own cell's bend (the pull is at most half a clump, smaller than the wind's eddies).
- **Patches** (``field.patchiness``, ``field.patch_size``): low-frequency value noise, three octaves
  at the patch size, a third of it and three times it, scales the blades' length (taller and
  shorter stands) and each species' share (a patch of flowers, a dry patch), metres to tens of
  metres wide. The widest octave is what the far canopy still shows from low eyes, where a pixel
  spans tens of metres of depth and averages the smaller patches away.
- **Heads** (species ``heads``, ``head_color``, ``head_size``, ``head_shape``): a share of a
  species' stems carry a seed head or a flower at their tip. A seed head widens the strip at its
  last joint but one, so the top two segments make a spindle (a panicle, a spike); a flower
  is a small head on a thin stem: its top two segments are only ``CUP_DEPTH`` times its width long
  (the stem's other segments share the rest of its length), the lower one opening from the stem
  to the flower's width, the upper one closing to its rim (``FLOWER_RIM``) (kinematics.py), not a
  flag a segment long. Both are in the head's colour (a flower's two segments wholly,
  ``segment_colours``) and ride the solver's own tip; cards and the far canopy take their shape
  and colour from the same blades.
- **Dry tips** (``blade.dry_tips``): a share of the blades fade to straw towards their tips.

Random numbers come from their own stream, ``np.random.default_rng([seed, RNG_MEADOW, block])``,
drawn after every draw of the plain field, so a field without variety is the same bits as before.
"""

from __future__ import annotations

import numpy as np

from . import blade, wind
from .schema import Params

RNG_MEADOW = 3  # purpose of the meadow's random stream (blocks.RNG_BLADES = 1, RNG_CELLS = 2)
STRAW = np.array([0.42, 0.34, 0.15], dtype=np.float32)  # linear RGB of a dry tip
PATCH_LENGTH = 0.45  # at patchiness 1 a patch's blades are 1 -+ this much of their length
PATCH_SHARE = 2.5  # at patchiness 1 a species' share varies by e^(+-this) from patch to patch (a species
# dominates a patch more with a larger value; 2.5 keeps the far canopy's one-L stands within a hundredth
# of the sky, tests/core/test_sward.py)
DRY_FROM = 0.45  # a dry blade is green up to this fraction of its length, straw at its tip
CUP_DEPTH = 0.7  # a flower's head (its top two segments) is this many times as tall as it is wide
FLOWER_RIM = 0.6  # a flower's tip joint is this share of its width (the head's rim)


def _hash01(seed: int, channel, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """A uniform number in [0, 1) for each integer lattice point (i, j), a pure function of
    (seed, channel, i, j) (SplitMix64's finaliser, ``wind.mix64``, over the packed key). The
    arguments broadcast: ``channel`` may be an array of channels (C, 1) against points (n,)."""
    with np.errstate(over="ignore"):
        x: np.ndarray = np.asarray(np.uint64(seed & 0xFFFFFFFF) * wind.GOLDEN
                                   ^ np.asarray(channel).astype(np.uint64) * wind.MIX1)
        x = x + i.astype(np.int64).astype(np.uint64) * wind.MIX2
        x = wind.mix64(x ^ (j.astype(np.int64).astype(np.uint64) * np.uint64(0xD6E8FEB86659FD93)))
    return (x >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def _lattice(seed: int, channels, i: np.ndarray, j: np.ndarray, pad: int):
    """(tables, row, column): ``_hash01`` of each channel on every lattice point of the box around
    the points (i, j) widened by ``pad`` each way, so that ``tables[k, row + di, column + dj]`` is
    ``_hash01(seed, channels[k], i + di, j + dj)`` for |di|, |dj| <= pad; None when the box holds
    more points than there are points (i, j) (then hashing each point costs less). The hashes of a
    block's blades lie on a few lattice points: one hash each instead of one a blade (the same bits)."""
    if not i.size:
        return None
    i0, j0 = i.min() - pad, j.min() - pad
    rows, cols = int(i.max() - i0) + 1 + pad, int(j.max() - j0) + 1 + pad
    if rows * cols > i.size:
        return None
    gi, gj = (np.arange(rows) + i0)[:, None], (np.arange(cols) + j0)[None, :]
    tables = _hash01(seed, np.asarray(channels)[:, None, None], gi, gj)
    return tables, (i - i0).astype(np.intp), (j - j0).astype(np.intp)


def value_noise(xy: np.ndarray, seed: int, channel: int, size: float) -> np.ndarray:
    """(n,) smooth noise in [0, 1] over points ``xy`` (n, 2) in metres: random values on a lattice
    of edge ``size``, blended by the smoothstep of the position between them."""
    return noise_channels(xy, seed, [channel], size)[0]


def noise_channels(xy: np.ndarray, seed: int, channels, size: float) -> np.ndarray:
    """(C, n) ``value_noise`` of each of ``channels`` at the same points: the lattice cells and
    blend weights are worked out once for all of them (each row the bits ``value_noise`` gives)."""
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2) / float(size)
    cell = np.floor(p)
    f = p - cell
    w = f * f * (3.0 - 2.0 * f)
    i, j = cell[:, 0], cell[:, 1]
    box = _lattice(seed, channels, i, j, 1)
    if box is None:
        ch = np.asarray(channels)[:, None]
        v00, v10 = _hash01(seed, ch, i, j), _hash01(seed, ch, i + 1, j)
        v01, v11 = _hash01(seed, ch, i, j + 1), _hash01(seed, ch, i + 1, j + 1)
    else:
        tables, r, c = box
        v00, v10, v01, v11 = tables[:, r, c], tables[:, r + 1, c], tables[:, r, c + 1], tables[:, r + 1, c + 1]
    bottom = v00 + (v10 - v00) * w[:, 0]
    top = v01 + (v11 - v01) * w[:, 0]
    return bottom + (top - bottom) * w[:, 1]


def patches(xy: np.ndarray, seed: int, channel: int, size: float) -> np.ndarray:
    """(n,) patch noise in [-1, 1]: three octaves of ``value_noise`` at ``size``, a third of it and
    three times it, spread so that the field's patches reach both ends (about 1 % clipped)."""
    return patch_channels(xy, seed, [channel], size)[0]


def patch_channels(xy: np.ndarray, seed: int, channels, size: float) -> np.ndarray:
    """(C, n) ``patches`` of each of ``channels`` at the same points (each row its bits)."""
    ch = np.asarray(channels, dtype=np.int64)
    a = noise_channels(xy, seed, 2 * ch + 101, size)
    b = noise_channels(xy, seed, 2 * ch + 102, size / 3.0)
    c = noise_channels(xy, seed, 2 * ch + 301, size * 3.0)
    return np.clip(3.2 * ((0.5 * a + 0.2 * b + 0.3 * c) - 0.5), -1.0, 1.0)


def clump_centres(xy: np.ndarray, seed: int, size: float) -> np.ndarray:
    """(n, 2) the nearest tussock centre to each point: one centre on each cell of the lattice of
    edge ``size``, jittered anywhere inside its cell (the 3 x 3 lattice cells around a point hold
    its nearest; of equally near ones, the first in the order below)."""
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    home = np.floor(p / size)
    d = np.array([-1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])[:, None], \
        np.array([-1.0, 0.0, 1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0])[:, None]
    i, j = home[:, 0] + d[0], home[:, 1] + d[1]  # (9, n) the lattice cells around each point
    box = _lattice(seed, [11, 12], home[:, 0], home[:, 1], 1)
    if box is None:
        jitter = _hash01(seed, 11, i, j), _hash01(seed, 12, i, j)
    else:
        tables, r, c = box
        rows, cols = r + d[0].astype(np.intp), c + d[1].astype(np.intp)
        jitter = tables[0, rows, cols], tables[1, rows, cols]
    cx, cy = (i + jitter[0]) * size, (j + jitter[1]) * size
    nearest = (((cx - p[:, 0]) ** 2) + ((cy - p[:, 1]) ** 2)).argmin(axis=0)
    at = np.arange(len(p))
    return np.stack([cx[nearest, at], cy[nearest, at]], axis=1)


def clumped(xy: np.ndarray, seed: int, clumping: float, size: float) -> np.ndarray:
    """(n, 2) roots ``xy`` pulled towards their tussock centres: ``c + (p - c) (1 - clumping)``."""
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if clumping <= 0.0:
        return p
    centre = clump_centres(p, seed, size)
    return centre + (p - centre) * (1.0 - float(clumping))


def length_scale(xy: np.ndarray, params: Params) -> np.ndarray:
    """(n,) the patches' scale of the blades' length at ``xy`` (1 without patches)."""
    f = params.field
    if f.patchiness <= 0.0:
        return np.ones(len(np.asarray(xy).reshape(-1, 2)))
    return 1.0 + PATCH_LENGTH * float(f.patchiness) * patches(xy, int(f.seed), 0, float(f.patch_size))


EDGE_FLOOR = 0.12  # a blade on the field's very edge is this share of its length
EDGE_RAGGED = 0.5  # the full-height line wanders in and out by this share of field.edge ...
EDGE_GRAIN = 0.4  # ... over this many metres (value noise)
EDGE_CHANNEL = 7


def edge_scale(xy: np.ndarray, origin, size, params: Params, ragged: bool = True) -> np.ndarray:
    """(n,) the field's edge's scale of the blades' length at ``xy`` (1 without ``field.edge``):
    from EDGE_FLOOR on the field's boundary (``origin``, ``size``: its rectangle) up to 1 at
    ``field.edge`` metres inside it, a smoothstep along a ragged line (the distance in wanders by
    EDGE_RAGGED of the width, value noise of EDGE_GRAIN m; ``ragged`` False: a straight one, the
    far grass's mean), so the edge seen from outside thins out as a meadow's does instead of
    standing as a wall."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    width = float(params.field.edge)
    if width <= 0.0 or not len(xy):
        return np.ones(len(xy))
    x0, y0 = float(origin[0]), float(origin[1])
    x1, y1 = x0 + float(size[0]), y0 + float(size[1])
    inside = np.minimum(np.minimum(xy[:, 0] - x0, x1 - xy[:, 0]), np.minimum(xy[:, 1] - y0, y1 - xy[:, 1]))
    wander = (EDGE_RAGGED * width * (2.0 * value_noise(xy, int(params.field.seed), EDGE_CHANNEL, EDGE_GRAIN) - 1.0)
              if ragged else 0.0)
    u = np.clip((inside + wander) / width, 0.0, 1.0)
    return EDGE_FLOOR + (1.0 - EDGE_FLOOR) * u * u * (3.0 - 2.0 * u)


def species_weights(xy: np.ndarray, params: Params, weights: np.ndarray) -> np.ndarray | None:
    """(n, species) each species' share at ``xy``, changed patch by patch (every species its own
    noise), or None without patches or with one species. Flowers grow in drifts: a species whose
    heads are flowers (``drifts``) varies ``field.flower_drift`` times as much, divided by how much
    more that raises its mean over the field (``_mean_gain``), so its share of the whole field stays."""
    f = params.field
    if f.patchiness <= 0.0 or len(weights) < 2:
        return None
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(xy), len(weights)))
    base = PATCH_SHARE * float(f.patchiness)
    noise = patch_channels(xy, int(f.seed), np.arange(1, len(weights) + 1), float(f.patch_size))
    for k, (w, drift) in enumerate(zip(weights, drifts(params.species()))):
        contrast = base * (float(f.flower_drift) if drift else 1.0)
        gain = _mean_gain(base) / _mean_gain(contrast)
        out[:, k] = w * gain * np.exp(contrast * noise[k])
    return out


FLOWER_SHAPES = ("flower", "daisy", "buttercup", "clover")  # head shapes that are flowers (heads.MESH_SHAPES)


def drifts(rows) -> np.ndarray:
    """(species,) bool: the species' heads are flowers (its ``heads`` share of stems flower)."""
    return np.array([r["head_shape"] in FLOWER_SHAPES and r["heads"] > 0.0 for r in rows], dtype=bool)


_GAINS: dict = {}


def _mean_gain(contrast: float) -> float:
    """The mean over a field of exp(contrast * patches): measured once on 65,536 points of a
    square 128 patches wide (the noise's law is the same for every seed, channel and size)."""
    key = round(float(contrast), 9)
    if key not in _GAINS:
        side = np.linspace(0.0, 128.0, 256, endpoint=False)
        xy = np.stack(np.meshgrid(side, side), axis=-1).reshape(-1, 2)
        _GAINS[key] = float(np.exp(contrast * patches(xy, 0, 1, 1.0)).mean())
    return _GAINS[key]


def heads_and_dryness(rng: np.random.Generator, kind: np.ndarray, species, params: Params) -> tuple:
    """(head, flower, dry) per blade: the width of a seed head at the stem's last joint but one and
    of a flower at its tip, as multiples of the stem's root width (0: none; ``head_size`` of the
    species on its ``heads`` share of stems, by its ``head_shape``), and how dry its tip is (0..1;
    ``blade.dry_tips`` of the blades, uniformly 0.5..1)."""
    count = len(kind)
    u_head, u_dry, dryness = rng.random(count), rng.random(count), rng.random(count)
    size = np.where(u_head < species.heads[kind], species.head_size[kind], 0.0).astype(np.float32)
    flower = species.flower[kind]
    dry = np.where(u_dry < float(params.blade.dry_tips), 0.5 + 0.5 * dryness, 0.0).astype(np.float32)
    return np.where(flower, 0.0, size).astype(np.float32), np.where(flower, size, 0.0).astype(np.float32), dry


def head_widening(head: np.ndarray, tip_width: float, n: int, joint: int) -> np.ndarray:
    """(B,) float32: the factor on a blade's width at ``joint`` that makes it ``head`` times the
    stem's root width there (1 where there is no head, or where the taper is already wider)."""
    taper = blade.joint_widths(tip_width, n)[joint]
    return np.maximum(np.asarray(head, dtype=np.float32) / np.float32(taper), np.float32(1.0))


def flower_segments(n: int) -> int:
    """How many top segments of an n-segment stem make its flower: two (opening, closing), one on
    stems of fewer than three segments."""
    return 2 if n >= 3 else 1


def widened_joints(n: int, head: np.ndarray, flower: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """[(joint, width as a multiple of the root width (0: not widened))]: a seed head at joint
    n - 1; a flower its full width at joint n - 1 and its rim at the tip (at the tip alone on
    stems of fewer than three segments)."""
    flower = np.asarray(flower, dtype=np.float32)
    out = [(n - 1, np.maximum(np.asarray(head, dtype=np.float32), flower if n >= 3 else 0.0))] if n >= 2 else []
    out.append((n, flower * np.float32(FLOWER_RIM if n >= 3 else 1.0)))
    return [(joint, width) for joint, width in out if joint >= 1]


def joint_widths(tip_width: float, n: int, head: np.ndarray, flower: np.ndarray) -> np.ndarray:
    """(B, n + 1) each joint's width as a fraction of the blade's root width: the taper
    (blade.joint_widths), widened by a seed head or a flower (``widened_joints``)."""
    out = np.repeat(blade.joint_widths(tip_width, n)[None, :], len(head), axis=0)
    for joint, width in widened_joints(n, head, flower):
        out[:, joint] *= head_widening(width, tip_width, n, joint)
    return out


def joint_colours(n: int, colour: np.ndarray, head_colour: np.ndarray, dry: np.ndarray, head: np.ndarray,
                  flower: np.ndarray) -> np.ndarray:
    """(..., n + 1, 3) float32 linear RGB at each joint of blades of tip ``colour`` (..., 3): it
    fades to straw towards a dry tip (``dry``), and takes ``head_colour`` from joint n - 1 on for
    a seed head (the spindle over the top two segments) and for a flower (its head; at the tip
    alone on stems of fewer than three segments)."""
    colour = np.asarray(colour, dtype=np.float32)[..., None, :]
    t = np.arange(n + 1, dtype=np.float32) / n
    ramp = np.clip((t - DRY_FROM) / (1.0 - DRY_FROM), 0.0, 1.0)
    out = colour + (STRAW - colour) * (np.asarray(dry, dtype=np.float32)[..., None, None] * ramp[:, None])
    heads = np.asarray(head_colour, dtype=np.float32)[..., None, :]
    for first, width in ((n - 1, head), (n + 1 - flower_segments(n), flower)):
        if first >= 1:
            headed = (np.asarray(width) > 0.0)[..., None, None]
            out[..., first:, :] = np.where(headed, heads, out[..., first:, :])
    return out.astype(np.float32)


def segment_shares(n: int, length: np.ndarray, width: np.ndarray, flower: np.ndarray) -> np.ndarray:
    """(B, n) each segment's share of its blade's length: 1/n, except on a stem with a flower,
    whose head (its top ``flower_segments``) is ``CUP_DEPTH`` times the flower's width tall (at
    most their 1/n each), the stem's other segments sharing the rest evenly. ``width`` is the
    blade's root width (m), ``flower`` the flower's width as a multiple of it (0: none)."""
    length = np.asarray(length, dtype=np.float64)
    shares = np.full((len(length), n), 1.0 / n)
    opened = np.asarray(flower) > 0.0
    k = flower_segments(n)
    if n < 2 or not opened.any():
        return shares
    head = CUP_DEPTH * np.asarray(flower, np.float64)[opened] * np.asarray(width, np.float64)[opened]
    head = np.minimum(head / np.maximum(length[opened], 1e-9), k / n)
    shares[opened, n - k:] = (head / k)[:, None]
    shares[opened, : n - k] = ((1.0 - head) / (n - k))[:, None]
    return shares


def segment_colours(joints: np.ndarray, flower: np.ndarray) -> np.ndarray:
    """(..., n, 2, 3) float32 the colour at the bottom and the top of each segment, from the
    joints' colours ``joints`` (..., n + 1, 3) (``joint_colours``): a flower's head, its top
    ``flower_segments``, is its colour from bottom to top (not a fade from the green stem)."""
    joints = np.asarray(joints, dtype=np.float32)
    out = np.stack([joints[..., :-1, :], joints[..., 1:, :]], axis=-2)
    if out.shape[-3] < 2:  # a one-segment stem is all stem, its flower at the tip only
        return out
    first = out.shape[-3] - flower_segments(out.shape[-3])
    opened = (np.asarray(flower) > 0.0)[..., None]
    out[..., first, 0, :] = np.where(opened, out[..., first, 1, :], out[..., first, 0, :])
    return out
