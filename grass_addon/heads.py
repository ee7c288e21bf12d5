"""Flower heads as meshes, riding their stems' tips (numpy only; Blender instances them).

A species whose ``head_shape`` is one of ``MESH_SHAPES`` carries, on its ``heads`` share of stems,
a flower built here once, in a unit frame: the stem's tip at the origin, the stem's direction
+Z, the head's width 1 (it is scaled by the flower's width in metres, ``blade_flower`` times the
stem's root width). The stem itself stays a green strip to its tip (``crowned``); the solver's
tip carries the head every frame (``bridge/heads.py``: a Geometry Nodes modifier instances it at
each tip, turned to the stem's last segment). The cards and the far canopy draw a flower as a
spot of its colour (``atlas.py``), as they did the strip's flower.

Shapes, after the plants of a hay meadow:
  * ``daisy``: ox-eye daisy (Leucanthemum vulgare): about 20 white ray florets round a domed
    yellow disc a third of the head's width, a green involucre under it;
  * ``buttercup``: meadow buttercup (Ranunculus acris): five broad, cupped, glossy petals round a
    boss of darker stamens, five green sepals under them;
  * ``clover``: a red or white clover head (Trifolium): a ball of florets, browner at its base.

Every shape gives ``HeadMesh``: vertices, triangles and quads (faces as index lists), and per
vertex the part it belongs to: 0 petals or florets (the species' ``head_color``), 1 the centre
(``CENTRES``: the disc, the stamens), 2 green (involucre, sepals); and a roughness (glossy
buttercup petals).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import tufts

MESH_SHAPES = ("daisy", "buttercup", "clover")
SEED_SHAPES = ("spike", "panicle")  # grasses' seed heads as meshes over the stem's top two segments
SPAN_SCALED = ("panicle",)  # seed heads Blender scales evenly by that span (a spike: its width across)
PETALS, CENTRE, GREEN = 0, 1, 2
CENTRES = {"daisy": (0.78, 0.45, 0.02), "buttercup": (0.42, 0.36, 0.03), "clover": (0.30, 0.18, 0.10),
           "spike": (0.30, 0.20, 0.30), "panicle": (0.20, 0.24, 0.10)}
GREEN_RGB = (0.08, 0.22, 0.04)


@dataclass(frozen=True)
class HeadMesh:
    vertices: np.ndarray  # (V, 3) float32, unit frame
    faces: list  # [tuple of vertex ids], each a triangle or a quad
    part: np.ndarray  # (V,) int8: PETALS, CENTRE or GREEN
    roughness: np.ndarray  # (V,) float32


@dataclass(frozen=True)
class _Builder:
    """Vertices and faces added part by part."""

    verts: list
    faces: list
    part: list
    rough: list

    def add(self, points, faces, part, roughness: float) -> None:
        """``points`` (k, 3); ``faces``: vertex id tuples of them; ``part``: one for all or (k,)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        base = len(self.verts)
        self.verts.extend(points.tolist())
        self.faces.extend(tuple(int(i) + base for i in f) for f in faces)
        self.part.extend(np.broadcast_to(np.asarray(part, dtype=np.int64), (len(points),)).tolist())
        self.rough.extend([roughness] * len(points))


def _grid_faces(rows: int, cols: int) -> np.ndarray:
    """Quads of a (rows x cols) grid of points, row-major."""
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    a = (r * cols + c).ravel()
    return np.stack([a, a + 1, a + cols + 1, a + cols], axis=1)


def _dome(b: _Builder, radius: float, height: float, z0: float, part: int, rough: float, rings: int = 3,
          sides: int = 12) -> None:
    """A shallow dome (a disc, a boss) of ``radius`` rising ``height`` above ``z0``."""
    t = np.linspace(1.0, 0.0, rings + 1)[:-1]  # from the rim in
    a = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros(sides)], axis=1)
    pts = [ring * np.array([radius * ti, radius * ti, 0.0]) + np.array([0.0, 0.0, z0 + height * (1.0 - ti ** 2)])
           for ti in t]
    pts.append(np.array([[0.0, 0.0, z0 + height]]))
    points = np.concatenate(pts)
    faces: list[tuple[int, ...]] = []
    for k in range(rings - 1):
        for s in range(sides):
            i, j = k * sides + s, k * sides + (s + 1) % sides
            faces.append((i, j, j + sides, i + sides))
    top = rings * sides
    faces += [((rings - 1) * sides + s, (rings - 1) * sides + (s + 1) % sides, top) for s in range(sides)]
    b.add(points, faces, part, rough)


def _cone_under(b: _Builder, radius: float, depth: float, sides: int = 10) -> None:
    """The green cup under a head (involucre): from ``radius`` at z = 0 to the stem at -``depth``."""
    a = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    top = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(sides)], axis=1)
    bottom = np.stack([0.25 * radius * np.cos(a), 0.25 * radius * np.sin(a), np.full(sides, -depth)], axis=1)
    faces = [(s, (s + 1) % sides, sides + (s + 1) % sides, sides + s) for s in range(sides)]
    b.add(np.concatenate([top, bottom]), faces, GREEN, 0.6)


def _petal(b: _Builder, angle: float, r0: float, r1: float, widths, lift, cup: float, part: int,
           rough: float) -> None:
    """One petal or ray along azimuth ``angle`` from radius ``r0`` to ``r1``: sections of ``widths``
    (across), heights ``lift`` (z at each section), its edges raised by ``cup`` (a cupped petal)."""
    widths, lift = np.asarray(widths, float), np.asarray(lift, float)
    r = np.linspace(r0, r1, len(widths))
    across = np.array([-1.0, 0.0, 1.0])
    along_dir = np.array([np.cos(angle), np.sin(angle), 0.0])
    side_dir = np.array([-np.sin(angle), np.cos(angle), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    w = widths[:, None, None]
    pts = (r[:, None, None] * along_dir + (0.5 * w * across[None, :, None]) * side_dir
           + (lift[:, None, None] + cup * w * np.abs(across)[None, :, None]) * up)
    b.add(pts.reshape(-1, 3), _grid_faces(len(widths), 3).tolist(), part, rough)


def daisy(rays: int = 21) -> HeadMesh:
    b = _Builder([], [], [], [])
    _dome(b, 0.17, 0.07, 0.0, CENTRE, 0.8)
    _cone_under(b, 0.19, 0.12)
    for k in range(rays):
        a = 2.0 * np.pi * (k + 0.37 * (k % 3)) / rays
        droop = 0.03 * ((k * 7) % 5) / 4.0
        _petal(b, a, 0.14, 0.5, widths=(0.03, 0.075, 0.08, 0.07, 0.02),
               lift=(0.02, 0.03, 0.025 - droop * 0.5, 0.01 - droop, -0.01 - 1.5 * droop), cup=0.15, part=PETALS,
               rough=0.55)
    return _mesh(b)


def buttercup(petals: int = 5) -> HeadMesh:
    b = _Builder([], [], [], [])
    _dome(b, 0.13, 0.09, 0.01, CENTRE, 0.5)
    for k in range(petals):  # sepals, between the petals, folded down
        a = 2.0 * np.pi * (k + 0.5) / petals
        _petal(b, a, 0.05, 0.3, widths=(0.05, 0.14, 0.12, 0.03), lift=(-0.02, -0.06, -0.1, -0.14), cup=0.2,
               part=GREEN, rough=0.6)
    for k in range(petals):  # broad obovate petals, overlapping, rising into a cup
        a = 2.0 * np.pi * k / petals
        _petal(b, a, 0.06, 0.48, widths=(0.12, 0.3, 0.38, 0.36, 0.22), lift=(0.0, 0.04, 0.1, 0.17, 0.23), cup=0.35,
               part=PETALS, rough=0.12)
    return _mesh(b)


def clover(sides: int = 10, rings: int = 7) -> HeadMesh:
    """A ball of florets: a sphere whose surface is lumpy (florets) and whose base is browner."""
    b = _Builder([], [], [], [])
    theta = np.linspace(0.0, np.pi, rings + 2)[1:-1]  # from the top down
    phi = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    lump = 1.0 + 0.12 * np.cos(5.0 * ph + 3.0 * th) * np.sin(4.0 * th)
    rad = 0.5 * lump
    pts = np.stack([rad * np.sin(th) * np.cos(ph), rad * np.sin(th) * np.sin(ph), 0.35 + 0.45 * np.cos(th)], axis=-1)
    pts = np.concatenate([pts.reshape(-1, 3), [[0.0, 0.0, 0.8]], [[0.0, 0.0, -0.1]]])
    faces: list[tuple[int, ...]] = [
        (r * sides + s, r * sides + (s + 1) % sides, (r + 1) * sides + (s + 1) % sides, (r + 1) * sides + s)
        for r in range(rings - 1) for s in range(sides)]
    top, bottom = rings * sides, rings * sides + 1
    faces += [((s + 1) % sides, s, top) for s in range(sides)]
    last = (rings - 1) * sides
    faces += [(last + s, last + (s + 1) % sides, bottom) for s in range(sides)]
    b.add(pts, faces, np.where(np.arange(len(pts)) >= (rings - 2) * sides, CENTRE, PETALS), 0.7)
    return _mesh(b)


def spike(rings: int = 14, sides: int = 8) -> HeadMesh:
    """A grass's dense cylindrical spike (timothy, Phleum pratense) over the stem's top segment:
    from z = 0 (its joint n - 1) to z = 1 (its tip), 1 wide (the seed head's width), rounded at
    both ends; its surface lumpy with spikelets in spirals, their purple anthers (the centre's
    colour) on a fifth of them."""
    b = _Builder([], [], [], [])
    z = np.linspace(0.0, 1.0, rings)
    ends = np.sqrt(np.clip(np.minimum(z / 0.08, (1.0 - z) / 0.12), 0.0, 1.0))  # rounded base and tip
    a = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    zz, aa = np.meshgrid(z, a, indexing="ij")
    lump = 1.0 + 0.18 * np.cos(3.0 * aa + 23.0 * zz)  # spikelets in spirals
    r = 0.5 * ends[:, None] * lump
    pts = np.stack([r * np.cos(aa), r * np.sin(aa), zz], axis=-1).reshape(-1, 3)
    faces = [(i * sides + j, i * sides + (j + 1) % sides, (i + 1) * sides + (j + 1) % sides, (i + 1) * sides + j)
             for i in range(rings - 1) for j in range(sides)]
    part = np.where((np.arange(len(pts)) * 7) % 5 == 0, CENTRE, PETALS)
    b.add(pts, faces, part, 0.7)
    return _mesh(b)


def panicle(whorls: int = 5, branches: int = 4, spikelets: int = 5) -> HeadMesh:
    """An open grass panicle (meadow grass, Poa; cocksfoot's is denser) over the stem's top two
    segments, in units of that span (Blender scales it evenly: z 0 at the stem's joint n - 2, 1
    at its tip): a thin axis to the tip, whorls of branches spreading 35-60 degrees from it
    (longest at the bottom: a pyramid about 0.6 of its length across), each with five lozenge
    spikelets 5 % of the span long (the head's colour) along its outer part, as much of them as the
    spindle the far grass and the cards draw for it (half the seed head's width times the span);
    the axis and branches the centre's green-straw."""
    b = _Builder([], [], [], [])
    b.add([(-0.005, 0, 0), (0.005, 0, 0), (0.002, 0, 1.0), (-0.002, 0, 1.0)], [(0, 1, 2, 3)], CENTRE, 0.7)
    rng = np.random.default_rng(13)
    for w in range(whorls):
        z0 = 0.08 + 0.7 * w / max(1, whorls - 1)
        length = 0.36 * (1.0 - 0.7 * w / max(1, whorls - 1))  # the lowest branches longest
        for k in range(branches):
            azimuth = 2.0 * np.pi * (k + 0.3 * w + 0.2 * rng.random()) / branches
            lift = np.radians(35.0 + 25.0 * rng.random())  # from the axis
            out = np.array([np.sin(lift) * np.cos(azimuth), np.sin(lift) * np.sin(azimuth), np.cos(lift)])
            side = np.array([-np.sin(azimuth), np.cos(azimuth), 0.0]) * 0.002
            foot = np.array([0.0, 0.0, z0])
            end = foot + length * out
            b.add([foot - side, foot + side, end + side, end - side], [(0, 1, 2, 3)], CENTRE, 0.7)
            across = np.array([-np.sin(azimuth), np.cos(azimuth), 0.0]) * 0.01
            for t in np.linspace(0.4, 1.0, spikelets):  # spikelets along the branch's outer part
                c = foot + t * length * out
                up = 0.05 * out
                b.add([c, c + 0.5 * up + across, c + up, c + 0.5 * up - across], [(0, 1, 2, 3)], PETALS, 0.6)
    return _mesh(b)


def _mesh(b: _Builder) -> HeadMesh:
    return HeadMesh(np.asarray(b.verts, dtype=np.float32), list(b.faces), np.asarray(b.part, dtype=np.int8),
                    np.asarray(b.rough, dtype=np.float32))


_BUILD = {"daisy": daisy, "buttercup": buttercup, "clover": clover, "spike": spike, "panicle": panicle}


def head_mesh(shape: str) -> HeadMesh:
    """The unit mesh of ``shape`` (one of ``MESH_SHAPES`` or ``SEED_SHAPES``)."""
    return _BUILD[shape]()


def colours(mesh: HeadMesh, shape: str, petals) -> np.ndarray:
    """(V, 3) float32 linear RGB per vertex: ``petals`` (the species' head colour) on the petals or
    florets, the shape's centre colour on its centre, green under it."""
    table = np.array([petals, CENTRES[shape], GREEN_RGB], dtype=np.float32)
    return table[mesh.part.astype(np.int64)]


NONE, HEAD, PLANT, SEED = 0, 1, 2, 3  # what a species' stems carry: nothing more, a mesh head, a whole
# plant, a seed head as a mesh over the top two segments


def kinds(rows) -> np.ndarray:
    """(species,) int8 of the species table's rows: ``HEAD`` where its flowers are meshes (a
    Windgrass shape, or the artist's own collection drawn as a head), ``PLANT`` where its stems
    are the artist's own plant bent along them, ``SEED`` where its seed heads are meshes (a spike
    or a panicle over the stem's top two segments, which the strip draws unwidened), ``NONE``
    else."""
    def kind(r) -> int:
        if r.get("plant") and r.get("plant_mode") == "plant":
            return PLANT
        if (r.get("plant") or r["head_shape"] in MESH_SHAPES) and r["heads"] > 0.0:
            return HEAD
        if r["head_shape"] in SEED_SHAPES and r["heads"] > 0.0:
            return SEED
        return NONE
    return np.array([kind(r) for r in rows], dtype=np.int8)


def carries_any(layout) -> bool:
    """Whether some species of ``layout`` carries a mesh head, is a plant (``kinds``) or has
    leaves at its stems' foot (``tufts.leafy``)."""
    rows = layout.params.species()
    return bool((kinds(rows) != NONE).any() or tufts.leafy(rows).any())


def crowned(rows) -> np.ndarray:
    """(species,) bool: the species' flowers are meshes, not the strip's cup (``kinds``)."""
    return kinds(rows) == HEAD


def crowned_blades(layout, blades=None) -> np.ndarray:
    """(blades,) bool: the blades (of ``layout``, all or the ids ``blades``) whose flower is a mesh:
    their strips stay green stems, neither widened nor coloured at the tip."""
    kind = layout.blade_species if blades is None else layout.blade_species[blades]
    flower = layout.blade_flower if blades is None else layout.blade_flower[blades]
    return (flower > 0.0) & crowned(layout.params.species())[kind]


def strip_heads(layout, blades=None) -> np.ndarray:
    """``blade_head`` of the blades as their strips draw it: 0 where the seed head is a mesh
    (``SEED``: the strip stays a stem; its top two segments keep the head's colour, and the far
    grass and the cards still draw the spindle the mesh stands for)."""
    kind = layout.blade_species if blades is None else layout.blade_species[blades]
    head = layout.blade_head if blades is None else layout.blade_head[blades]
    return np.where(kinds(layout.params.species())[kind] == SEED, np.float32(0.0), head).astype(np.float32)


def strip_flowers(layout, blades=None) -> np.ndarray:
    """``blade_flower`` of the blades as their strips draw it: 0 where the flower is a mesh."""
    flower = layout.blade_flower if blades is None else layout.blade_flower[blades]
    return np.where(crowned_blades(layout, blades), np.float32(0.0), flower).astype(np.float32)


def tip_marks(layout, local: np.ndarray) -> np.ndarray:
    """(positions * verts_per_block, 5) float32 per vertex of the blade slot positions ``local``
    (FREE: zero), what Blender draws on each stem: on the first vertex of a stem that carries a
    mesh head or seed head, has leaves at its foot (``tufts``) or is a whole plant: the species +
    1, the flower's or seed head's width in metres (0: no head on this stem; a plant: the stem's
    length), a turn about
    the stem (the blade's facing), that vertex's index in its slot object, and the length of the
    longest leaf at its foot (m; 0: none); a plant's mark on every vertex of its strip (which
    Blender collapses); zero elsewhere. The index lets Blender read the stem's joints from the
    strip without a pass over every vertex. A stem collapsed onto its root (eq 9) or a free
    position has no last segment: nothing is drawn there."""
    n, bpb = layout.segments, layout.blades_per_block
    per_stem = 2 * (n + 1)
    out = np.zeros((len(local), bpb, per_stem, 5), dtype=np.float32)
    shown = local >= 0
    blades = local[shown, None].astype(np.int64) * bpb + np.arange(bpb)[None, :]
    kind = kinds(layout.params.species())[layout.blade_species[blades]]
    crown = (kind == HEAD) & (layout.blade_flower[blades] > 0.0)
    seed = (kind == SEED) & (layout.blade_head[blades] > 0.0)
    plant = kind == PLANT
    alive = None if layout.blade_alive is None else layout.blade_alive[blades]
    leaf = tufts.leaf_lengths(layout.params.species(), layout.blade_species[blades], layout.blade_length[blades], alive)
    marked = crown | seed | plant | (leaf > 0.0)
    size = np.where(plant, layout.blade_length[blades],
                    np.where(crown, layout.blade_flower[blades] * layout.blade_width[blades],
                             np.where(seed, layout.blade_head[blades] * layout.blade_width[blades], 0.0)))
    first = (np.flatnonzero(shown)[:, None] * bpb + np.arange(bpb)[None, :]) * per_stem  # (objects' positions
    # are their slots' k blocks in order: an object's vertex index is this modulo its vertex count)
    mark = np.stack([np.where(marked, layout.blade_species[blades] + 1.0, 0.0), size,
                     np.where(marked, layout.blade_facing[blades], 0.0), first, leaf], axis=-1) * marked[..., None]
    out[shown, :, 0] = mark
    out[shown] = np.where(plant[..., None, None], mark[:, :, None, :], out[shown])
    return out.reshape(-1, 5)


def triangles(mesh: HeadMesh) -> np.ndarray:
    """(T, 3) vertex ids: every face fanned into triangles."""
    return np.array([(f[0], f[i], f[i + 1]) for f in mesh.faces for i in range(1, len(f) - 1)], dtype=np.int64)


def placed(mesh: HeadMesh, tips: np.ndarray, directions: np.ndarray, widths: np.ndarray,
           turns: np.ndarray) -> np.ndarray:
    """(heads, V, 3) the head's vertices as Blender places them (``bridge/heads.py``): turned by
    ``turns`` about its axis, its axis +Z turned the shortest way onto ``directions`` (the stems'
    last segments), scaled by ``widths`` (m), at ``tips``."""
    d = np.asarray(directions, np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    c, s = np.cos(turns), np.sin(turns)
    v = mesh.vertices.astype(np.float64)[None]
    v = np.stack([c[:, None] * v[..., 0] - s[:, None] * v[..., 1], s[:, None] * v[..., 0] + c[:, None] * v[..., 1],
                  np.broadcast_to(v[..., 2], (len(d), v.shape[1]))], axis=-1)
    # Rodrigues: the rotation about z x d by the angle between them
    axis = np.stack([-d[:, 1], d[:, 0], np.zeros(len(d))], axis=1)  # z x d
    sin_a, cos_a = np.linalg.norm(axis, axis=1), d[:, 2]
    k = axis / np.maximum(sin_a, 1e-12)[:, None]
    kv = np.cross(k[:, None, :], v)
    kdot = np.einsum("hj,hvj->hv", k, v)[..., None]
    v = v * cos_a[:, None, None] + kv * sin_a[:, None, None] + k[:, None, :] * kdot * (1.0 - cos_a)[:, None, None]
    return v * np.asarray(widths, np.float64)[:, None, None] + np.asarray(tips, np.float64)[:, None, :]
