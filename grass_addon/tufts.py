"""The leaves at a stem's foot: a grass tuft, clover leaves, a rosette (numpy only; Blender instances them).

Seen from above, a real meadow hides its soil under thousands of leaves per square metre (a
pasture: 3,000-5,000 tillers per m2 with up to three leaves each); the strips the solver bends are
its stems and longest blades, upright, so they hide little of the ground. A species whose
``leaves`` is one of ``LEAF_SHAPES`` carries at the foot of each stem a tuft of short leaves, built
here once in a unit frame (the stem's root at the origin, +Z up, the longest leaf 1 long): Blender
instances it on the stem's root (``bridge/heads.py``), its +Z along the stem's first segment (the
wind rocks a tuft with its tiller), turned about it by the stem's facing, scaled by ``leaf_size``
times the stem's length (``marks``). The strips' level of detail (eq 9) takes a tuft away with its
stem.

Shapes, after the plants of a hay meadow:
  * ``tuft``: a grass tussock's basal leaves, 10 narrow pointed blades arching out and over all
    round the root (Poa, Festuca, Dactylis); one of them straw-coloured where the meadow's tips are
    dry (``blade.dry_tips``): the dead leaves at a tussock's foot;
  * ``rosette``: broad spoon-shaped leaves lying out flat (plantain, ox-eye daisy, buttercup's
    basal leaves);
  * ``clover``: trifoliate leaves (Trifolium repens) held flat on upright stalks, each leaflet with
    its pale chevron.

Every shape gives ``LeafMesh``: vertices, quads and triangles, and per vertex where it is along its
leaf (``v``: 0 at the foot, 1 at the tip, as the blade material's root-to-tip gradient reads it),
its tint (the species' colour, straw on a dead leaf) and its shade (the blade material's hue and
value spread, ``sward.shade_value``), so that the tuft is lit and coloured as the blades are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEAF_SHAPES = ("tuft", "rosette", "clover")
RNG_LEAVES = 11  # purpose of the shapes' fixed random stream (np.random.default_rng([RNG_LEAVES, shape]))
STRAW = (0.42, 0.34, 0.15)  # linear RGB of a dead leaf (meadow.STRAW)


@dataclass(frozen=True)
class LeafMesh:
    vertices: np.ndarray  # (V, 3) float32, unit frame
    faces: list  # vertex id tuples, quads and triangles
    v: np.ndarray  # (V,) float32: 0 at the leaf's foot .. 1 at its tip
    dead: np.ndarray  # (V,) bool: a dead (straw) leaf
    shade: np.ndarray  # (V,) float32: 0..1, the leaf's hue and value shade
    leaf: np.ndarray  # (V,) int32: which leaf (a clover's stalk and its leaflets are one)

    def tints(self, colour, dry: float) -> np.ndarray:
        """(V, 3) float32 linear RGB: ``colour`` (the species'), straw on the dead leaves where the
        meadow's tips are ``dry`` (0: none dead, green)."""
        rgb = np.broadcast_to(np.asarray(colour, np.float32), (len(self.v), 3)).copy()
        rgb[self.dead] += (np.asarray(STRAW, np.float32) - rgb[self.dead]) * np.float32(min(1.0, 4.0 * dry))
        return rgb


class _Builder:
    def __init__(self):
        self.verts: list = []
        self.faces: list = []
        self.v: list = []
        self.dead: list = []
        self.shade: list = []
        self.leaf: list = []
        self.leaves = 0  # the leaf being built is number leaves - 1

    def strip(self, centre: np.ndarray, side: np.ndarray, widths: np.ndarray, v: np.ndarray, dead: bool,
              shade: float) -> None:
        """A leaf as a strip: joints ``centre`` (m + 1, 3), unit ``side`` vectors (m + 1, 3), full
        ``widths`` (m + 1,); a joint of width 0 is one vertex (a pointed tip)."""
        self.leaves += 1
        base = len(self.verts)
        left = centre - 0.5 * widths[:, None] * side
        right = centre + 0.5 * widths[:, None] * side
        ids = []
        for j in range(len(centre)):
            if widths[j] > 0.0:
                ids.append((len(self.verts), len(self.verts) + 1))
                self.verts += [left[j], right[j]]
                self._per_vertex(2, v[j], dead, shade)
            else:
                ids.append((len(self.verts), len(self.verts)))
                self.verts.append(centre[j])
                self._per_vertex(1, v[j], dead, shade)
        for (a, b), (c, d) in zip(ids[:-1], ids[1:]):
            self.faces.append((a, b, d, c) if c != d else (a, b, c))
        assert len(self.verts) > base

    def fan(self, centre: np.ndarray, rim: np.ndarray, v_centre: float, v_rim, shade: float, shade_rim) -> None:
        """A flat leaflet of the last leaf: triangles from ``centre`` (3,) to consecutive points of
        ``rim`` (k, 3)."""
        base = len(self.verts)
        self.verts.append(centre)
        self._per_vertex(1, v_centre, False, shade)
        for point, vr, sr in zip(rim, np.broadcast_to(v_rim, len(rim)), np.broadcast_to(shade_rim, len(rim))):
            self.verts.append(point)
            self._per_vertex(1, vr, False, sr)
        k = len(rim)
        self.faces += [(base, base + 1 + i, base + 1 + (i + 1) % k) for i in range(k)]

    def _per_vertex(self, count: int, v: float, dead: bool, shade: float) -> None:
        self.v += [float(v)] * count
        self.dead += [bool(dead)] * count
        self.shade += [float(shade)] * count
        self.leaf += [self.leaves - 1] * count

    def mesh(self) -> LeafMesh:
        return LeafMesh(np.asarray(self.verts, np.float32).reshape(-1, 3), self.faces,
                        np.asarray(self.v, np.float32), np.asarray(self.dead, bool), np.asarray(self.shade, np.float32),
                        np.asarray(self.leaf, np.int32))


def _arched(azimuth: float, length: float, tilt0: float, tilt1: float, segments: int, foot=(0.0, 0.0, 0.0)):
    """Joints (segments + 1, 3) of a leaf leaving ``foot`` along ``azimuth``, tilted ``tilt0`` from
    the vertical at its foot and ``tilt1`` at its tip (it arches over), and its side (3,)."""
    t = (np.arange(segments) + 0.5) / segments
    tilt = tilt0 + (tilt1 - tilt0) * t ** 1.4
    step = (length / segments) * np.stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth),
                                           np.cos(tilt)], axis=1)
    joints = np.asarray(foot, np.float64) + np.concatenate([np.zeros((1, 3)), np.cumsum(step, axis=0)])
    return joints, np.array([-np.sin(azimuth), np.cos(azimuth), 0.0])


def tuft(leaves: int = 10, segments: int = 4) -> LeafMesh:
    """A grass tussock's basal leaves: narrow (5 % of the longest leaf's length), pointed, rising
    15-40 degrees from the vertical and arching over to 70-110 degrees, their feet up to 6 % out
    from the root (a tussock's tillers), all round it; the last one dead."""
    rng = np.random.default_rng([RNG_LEAVES, 0])
    b = _Builder()
    profile = np.array([0.75, 1.0, 0.9, 0.6, 0.0])[:segments + 1] if segments == 4 else \
        np.maximum(1.0 - np.linspace(0.0, 1.0, segments + 1) ** 2, 0.0)
    for k in range(leaves):
        azimuth = 2.0 * np.pi * (k + 0.45 * rng.random()) / leaves
        length = 0.55 + 0.45 * rng.random()
        tilt0, tilt1 = np.radians(15.0 + 25.0 * rng.random()), np.radians(70.0 + 40.0 * rng.random())
        foot = 0.06 * rng.random() * np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
        joints, side = _arched(azimuth, length, tilt0, tilt1, segments, foot)
        b.strip(joints, np.broadcast_to(side, joints.shape), 0.05 * profile, np.linspace(0.0, 1.0, segments + 1),
                dead=k == leaves - 1, shade=float(rng.random()))
    return b.mesh()


def rosette(leaves: int = 6, segments: int = 4) -> LeafMesh:
    """Broad basal leaves lying out (plantain, daisy, buttercup): spoon-shaped, widest at two
    thirds of their length (28 % of the longest leaf's length), 55-75 degrees from the vertical at
    their foot, 80-95 at their tip, all round the root."""
    rng = np.random.default_rng([RNG_LEAVES, 1])
    b = _Builder()
    t = np.linspace(0.0, 1.0, segments + 1)
    profile = np.sin(np.pi * np.minimum(t * 0.75, 0.999)) ** 1.5  # narrow stalk, widest at 2/3, round tip
    profile[-1] = 0.0
    for k in range(leaves):
        azimuth = 2.0 * np.pi * (k + 0.35 * rng.random()) / leaves
        length = 0.6 + 0.4 * rng.random()
        tilt0, tilt1 = np.radians(55.0 + 20.0 * rng.random()), np.radians(80.0 + 15.0 * rng.random())
        joints, side = _arched(azimuth, length, tilt0, tilt1, segments)
        b.strip(joints, np.broadcast_to(side, joints.shape), 0.28 * profile, 0.35 + 0.65 * t, dead=False,
                shade=float(rng.random()))
    return b.mesh()


def clover(leaves: int = 4, rim: int = 9) -> LeafMesh:
    """White clover's leaves: stalks rising 10-35 degrees from the vertical, 0.55-1 long, each
    holding three obovate leaflets (0.34 long, 0.28 wide) out flat, 120 degrees apart, each with
    the pale chevron of the species across its middle."""
    rng = np.random.default_rng([RNG_LEAVES, 2])
    b = _Builder()
    for k in range(leaves):
        azimuth = 2.0 * np.pi * (k + 0.4 * rng.random()) / leaves
        length = 0.55 + 0.45 * rng.random()
        joints, side = _arched(azimuth, length, np.radians(10.0 + 25.0 * rng.random()),
                               np.radians(20.0 + 25.0 * rng.random()), 2)
        b.strip(joints, np.broadcast_to(side, joints.shape), np.full(3, 0.02), np.array([0.2, 0.6, 1.0]),
                dead=False, shade=0.5)
        top, shade = joints[-1], float(rng.random())
        turn = rng.random() * 2.0 * np.pi
        for leaflet in range(3):
            a = turn + 2.0 * np.pi * leaflet / 3.0
            along = np.array([np.cos(a), np.sin(a), 0.12])  # held out, a little raised
            across = np.array([-np.sin(a), np.cos(a), 0.0])
            s = np.linspace(0.0, 2.0 * np.pi, rim, endpoint=False)
            # obovate: narrow at the stalk, broadest beyond its middle
            outline = top + (0.17 * (1.0 - np.cos(s)))[:, None] * along + (0.14 * np.sin(s))[:, None] * across
            b.fan(top + 0.16 * along, outline, 1.0, 1.0, shade, np.where(np.abs(np.cos(s)) < 0.5, 1.0, shade))
    return b.mesh()


_BUILD = {"tuft": tuft, "rosette": rosette, "clover": clover}


def leaf_mesh(shape: str) -> LeafMesh:
    """The unit mesh of ``shape`` (one of ``LEAF_SHAPES``)."""
    return _BUILD[shape]()


def leafy(rows) -> np.ndarray:
    """(species,) bool of the species table's rows: its stems carry leaves at their foot."""
    return np.array([r.get("leaves", "none") in LEAF_SHAPES for r in rows], dtype=bool)


def leaf_lengths(rows, kind: np.ndarray, length: np.ndarray, alive: np.ndarray | None = None) -> np.ndarray:
    """(blades,) float32: the longest leaf of each stem's tuft (m): its species' (``kind`` into the
    table ``rows``) ``leaf_size`` times the stem's ``length``; 0 where its species has none or the
    blade does not grow (``alive`` false: paint)."""
    size = np.array([r.get("leaf_size", 0.0) if r.get("leaves", "none") in LEAF_SHAPES else 0.0 for r in rows],
                    np.float32)
    out = size[np.asarray(kind, np.int64)] * np.asarray(length, np.float32)
    if alive is not None:
        out = np.where(alive, out, np.float32(0.0))
    return out.astype(np.float32)


def triangles(mesh: LeafMesh) -> np.ndarray:
    """(T, 3) vertex ids: every face fanned into triangles."""
    return np.array([(f[0], f[i], f[i + 1]) for f in mesh.faces for i in range(1, len(f) - 1)], dtype=np.int64)


def area_from_above(mesh: LeafMesh) -> float:
    """The unit tuft's area seen from straight above (its triangles projected on the ground, summed:
    overlaps counted twice), in units of the longest leaf's length squared."""
    tri = mesh.vertices[triangles(mesh)].astype(np.float64)
    a, b = tri[:, 1, :2] - tri[:, 0, :2], tri[:, 2, :2] - tri[:, 0, :2]
    return float(0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum())


# --------------------------------------------------------------------------------------------
# The leaves as the far grass's look counts them (sward.py)

PROFILE_HEIGHTS = 129  # heights of the unit tuft at which ``profile`` tabulates what lies above


@dataclass(frozen=True)
class LeafProfile:
    """What lies above each of ``heights`` (the unit tuft's frame, 0 .. its top) of a shape's
    leaves, live ``[0]`` and dead ``[1]``: ``side`` the leaf area a horizontal ray sees (averaged
    over its directions: |n_xy| 2/pi of each triangle's area, as ``sward.sward_depth`` counts a
    blade's), ``top`` the area a vertical ray sees (|n_z| of it); each with the blade material's
    colour split as ``base`` and ``tip`` shares (its colour is base_colour * base + tip_colour *
    tip: ``sward.colour_ramp`` at the vertices' v, times their value shade)."""

    heights: np.ndarray  # (H,)
    side: np.ndarray  # (2, H)
    top: np.ndarray  # (2, H)
    side_base: np.ndarray
    side_tip: np.ndarray
    top_base: np.ndarray
    top_tip: np.ndarray


def profile(shape: str, ramp_end: float, shade_low: float, shade_span: float) -> LeafProfile:
    """The unit tuft of ``shape`` tabulated for the far grass (``LeafProfile``); ``ramp_end``,
    ``shade_low`` and ``shade_span``: the blade material's gradient and value shade
    (``sward.GRADIENT_END``, ``SHADE_LOW``, ``SHADE_SPAN``). Each triangle's area above a height
    is its share above it (between its lowest and highest corners, evenly)."""
    m = leaf_mesh(shape)
    ids = triangles(m)
    tri = m.vertices[ids].astype(np.float64)
    cross = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    side = np.hypot(cross[:, 0], cross[:, 1]) * (2.0 / np.pi)
    top = np.abs(cross[:, 2])
    u = np.clip(m.v[ids].astype(np.float64) / ramp_end, 0.0, 1.0)
    tip = (u * u * (3.0 - 2.0 * u) * (shade_low + shade_span * m.shade[ids])).mean(axis=1)
    base = (shade_low + shade_span * m.shade[ids]).mean(axis=1) - tip
    low, high = tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1)
    heights = np.linspace(0.0, float(high.max()), PROFILE_HEIGHTS)
    above = np.clip((high[None] - heights[:, None]) / np.maximum(high - low, 1e-9)[None], 0.0, 1.0)  # (H, T)
    dead = m.dead[ids[:, 0]]

    def split(weights):
        return np.stack([above[:, ~dead] @ weights[~dead], above[:, dead] @ weights[dead]])

    return LeafProfile(heights, split(side), split(top), split(side * base), split(side * tip), split(top * base),
                       split(top * tip))
