"""Where grass grows and how tall: painted maps and keep-out shapes (numpy only).

A ``Paint`` holds what the artist painted or placed on the field, in the field's frame:

* ``density``: a map of 0..1, the share of a cell's blades that grow there (white: all of them);
* ``length``: a map of 0..2 (stored 0..1 as an image, times LENGTH_RANGE), the scale of the blades'
  length there: 1 as grown, 0.5 mown to half;
* ``species``: per species row, a map that scales its share there (a patch of clover, a strip of
  dry grass);
* ``keep_out``: footprints (boxes, discs, the ground outline of objects) where nothing grows, with
  a ``margin`` around them and a ``falloff`` over which the grass thins back to full.

How a blade follows the paint (``blocks.make_block``): every blade draws its own uniform numbers
once, from its block's stream, whatever is painted. It grows where its number is below the local
density, takes the species its second number picks from the local shares (an inverse CDF: without
species maps the very pick ``Generator.choice`` makes), and its length is scaled by the local
length. So painting more grass adds blades and never moves the ones already there, and a stroke
changes only the blades under it. A paint is part of what a block is a function of (``fingerprint``).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import ParameterError
from .schema import BLENDER_SOURCES, Params

LENGTH_RANGE = 2.0  # a length map's white: blades twice their length
MIN_LENGTH_SCALE = 0.02  # below this a blade is mown to nothing: it does not grow


@dataclass(frozen=True, eq=False)
class Raster:
    """Values on a regular grid over a rectangle of the field: ``values`` (ny, nx), row 0 along
    y0 (the bottom of an image), pixel (i, j) centred at x0 + (i + 1/2) (x1 - x0) / nx. Bilinear
    between pixel centres, the edge value beyond them."""

    values: np.ndarray
    extent: tuple[float, float, float, float]
    name: str = "map"  # the setting it came from, for messages

    def __post_init__(self):
        v = np.ascontiguousarray(self.values, dtype=np.float32)
        if v.ndim != 2 or v.size == 0:
            raise ParameterError(self.name, f"a map needs a 2-D image of values, got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ParameterError(self.name, "the map holds values that are not finite numbers")
        x0, y0, x1, y1 = (float(c) for c in self.extent)
        check_extent(self.name, (x0, y0, x1, y1))
        v.setflags(write=False)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "extent", (x0, y0, x1, y1))

    def sample(self, xy) -> np.ndarray:
        """Bilinear values at points xy (..., 2) -> (...) float64."""
        xy = np.asarray(xy, dtype=np.float64)
        x0, y0, x1, y1 = self.extent
        ny, nx = self.values.shape
        u = np.clip((xy[..., 0] - x0) / (x1 - x0) * nx - 0.5, 0.0, nx - 1)
        v = np.clip((xy[..., 1] - y0) / (y1 - y0) * ny - 0.5, 0.0, ny - 1)
        i = np.minimum(np.floor(u), max(nx - 2, 0)).astype(np.intp)
        j = np.minimum(np.floor(v), max(ny - 2, 0)).astype(np.intp)
        fu, fv = u - i, v - j
        i1, j1 = np.minimum(i + 1, nx - 1), np.minimum(j + 1, ny - 1)
        a = self.values
        low = a[j, i] + (a[j, i1] - a[j, i]) * fu
        high = a[j1, i] + (a[j1, i1] - a[j1, i]) * fu
        return low + (high - low) * fv

    def fingerprint(self) -> str:
        h = hashlib.sha1(np.asarray(self.values.shape, np.int64).tobytes())
        h.update(self.values.tobytes())
        h.update(np.asarray(self.extent, np.float64).tobytes())
        return h.hexdigest()


def check_extent(name: str, extent) -> None:
    x0, y0, x1, y1 = (float(c) for c in extent)
    if not all(math.isfinite(c) for c in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
        raise ParameterError(name, f"extent {[x0, y0, x1, y1]} is not a rectangle (valid: [x0, y0, x1, y1] "
                             "in metres with x1 > x0 and y1 > y0)")


@dataclass(frozen=True, eq=False)
class KeepOut:
    """Footprints where nothing grows: triangles (T, 3, 2) on the ground, in the field's frame.
    Grass is gone within ``margin`` metres of a footprint and thins back in over ``falloff``."""

    triangles: np.ndarray
    margin: float = 0.0
    falloff: float = 0.0

    def __post_init__(self):
        t = np.ascontiguousarray(self.triangles, dtype=np.float64).reshape(-1, 3, 2)
        t.setflags(write=False)
        object.__setattr__(self, "triangles", t)

    @property
    def reach(self) -> float:
        return float(self.margin) + float(self.falloff)

    def bounds(self) -> tuple[float, float, float, float]:
        """xmin, ymin, xmax, ymax of everything the footprints affect."""
        lo, hi = self.triangles.reshape(-1, 2).min(axis=0), self.triangles.reshape(-1, 2).max(axis=0)
        r = self.reach
        return float(lo[0] - r), float(lo[1] - r), float(hi[0] + r), float(hi[1] + r)

    def factor(self, xy) -> np.ndarray:
        """How much grass grows at points xy (n, 2): 0 within the margin of a footprint, rising
        to 1 over the falloff beyond it (a smoothstep), 1 further away."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.ones(len(xy))
        if not len(self.triangles) or not len(xy):
            return out
        x0, y0, x1, y1 = self.bounds()
        near = np.flatnonzero((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))
        if near.size == 0:
            return out
        d = footprint_distance(xy[near], self.triangles, self.reach)
        if self.falloff > 0.0:
            s = np.clip((d - self.margin) / self.falloff, 0.0, 1.0)
            out[near] = s * s * (3.0 - 2.0 * s)
        else:
            out[near] = (d > self.margin).astype(np.float64)
        return out


def footprint_distance(points: np.ndarray, triangles: np.ndarray, reach: float, chunk: int = 4096) -> np.ndarray:
    """Distance from each point (n, 2) to the union of triangles (T, 3, 2): 0 inside one; beyond
    ``reach`` the value is only known to be >= reach (the triangles whose boxes are out of reach
    are skipped)."""
    out = np.full(len(points), np.inf)
    lo, hi = triangles.min(axis=1) - reach, triangles.max(axis=1) + reach
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk]
        box = ((p[:, None, 0] >= lo[None, :, 0]) & (p[:, None, 0] <= hi[None, :, 0])
               & (p[:, None, 1] >= lo[None, :, 1]) & (p[:, None, 1] <= hi[None, :, 1]))
        rows, tris = np.nonzero(box)
        if rows.size == 0:
            continue
        d = _point_triangle_distance(p[rows], triangles[tris])
        best = np.full(len(p), np.inf)
        np.minimum.at(best, rows, d)
        out[start:start + chunk] = best
    return out


def _point_triangle_distance(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Distance of points p (m, 2) to triangles t (m, 3, 2) (0 inside), pair by pair."""
    a, b, c = t[:, 0], t[:, 1], t[:, 2]

    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    s1, s2, s3 = cross(b - a, p - a), cross(c - b, p - b), cross(a - c, p - c)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))

    def segment(u, v):
        e = v - u
        length2 = np.maximum((e * e).sum(axis=1), 1e-30)
        s = np.clip(((p - u) * e).sum(axis=1) / length2, 0.0, 1.0)
        q = u + e * s[:, None]
        return np.hypot(p[:, 0] - q[:, 0], p[:, 1] - q[:, 1])

    d = np.minimum(np.minimum(segment(a, b), segment(b, c)), segment(c, a))
    return np.where(inside, 0.0, d)


def box_triangles(center, size, angle_deg: float = 0.0) -> np.ndarray:
    """(2, 3, 2) triangles of a rectangle ``size`` (width, depth) centred on ``center``, turned by
    ``angle_deg`` counter-clockwise."""
    w, d = 0.5 * float(size[0]), 0.5 * float(size[1])
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    corners = np.array([(-w, -d), (w, -d), (w, d), (-w, d)]) @ np.array([[c, s], [-s, c]]) + np.asarray(center[:2])
    return np.array([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]])


def disc_triangles(center, radius: float, sides: int = 48) -> np.ndarray:
    """(sides, 3, 2) triangles of a disc (a polygon whose edges stay within 0.2 % of the radius)."""
    a = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], axis=1) * float(radius) / math.cos(math.pi / sides) \
        + np.asarray(center[:2])
    c = np.broadcast_to(np.asarray(center[:2], dtype=np.float64), (sides, 2))
    return np.stack([c, ring, np.roll(ring, -1, axis=0)], axis=1)


@dataclass(frozen=True, eq=False)
class Paint:
    """The maps and keep-out shapes of a field (any may be None: nothing painted there)."""

    density: Raster | None = None
    length: Raster | None = None
    species: tuple = field(default_factory=tuple)  # (Raster | None) per species row
    keep_out: KeepOut | None = None

    @property
    def empty(self) -> bool:
        return (self.density is None and self.length is None and self.keep_out is None
                and not any(m is not None for m in self.species))

    @property
    def thins(self) -> bool:
        """Whether some blades may not grow (density, keep-out or species maps)."""
        return self.density is not None or self.keep_out is not None or any(m is not None for m in self.species)

    def density_at(self, xy) -> np.ndarray:
        """Share of the blades that grow at points xy (n, 2): the density map times keep-out."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.ones(len(xy)) if self.density is None else np.clip(self.density.sample(xy), 0.0, 1.0)
        if self.keep_out is not None:
            out = out * self.keep_out.factor(xy)
        return out

    def length_at(self, xy) -> np.ndarray:
        """Scale of the blades' length at points xy (n,): 1 without a length map."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if self.length is None:
            return np.ones(len(xy))
        return np.clip(self.length.sample(xy), 0.0, 1.0) * LENGTH_RANGE

    def species_weights_at(self, xy, weights: np.ndarray) -> np.ndarray | None:
        """(n, species) local shares (the rows' weights times their maps), or None without maps."""
        if not any(m is not None for m in self.species):
            return None
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.broadcast_to(np.asarray(weights, dtype=np.float64), (len(xy), len(weights))).copy()
        for k, m in enumerate(self.species[:len(weights)]):
            if m is not None:
                out[:, k] *= np.clip(m.sample(xy), 0.0, 1.0)
        return out

    def fingerprint(self) -> str:
        h = hashlib.sha1(b"paint")
        for name, m in (("density", self.density), ("length", self.length)):
            h.update(f"{name}:{m.fingerprint() if m is not None else '-'}".encode())
        for i, m in enumerate(self.species):
            h.update(f"species{i}:{m.fingerprint() if m is not None else '-'}".encode())
        if self.keep_out is not None:
            k = self.keep_out
            h.update(k.triangles.tobytes() + np.array([k.margin, k.falloff], np.float64).tobytes())
        return h.hexdigest()


def fingerprint(paint: Paint | None) -> str:
    return "" if paint is None or paint.empty else paint.fingerprint()


def field_extent(params: Params) -> tuple[float, float, float, float]:
    """The field's rectangle in its own frame (centred on the origin)."""
    from .grid import FieldGrid

    grid = FieldGrid.of(params)
    (x0, y0), (w, h) = grid.origin, grid.size
    return float(x0), float(y0), float(x0 + w), float(y0 + h)


def map_extent(params: Params, extent, name: str) -> tuple[float, float, float, float]:
    """``extent`` as given ([x0, y0, x1, y1]), or the field's when it is all zeros."""
    if not any(float(c) for c in extent):
        return field_extent(params)
    check_extent(name, extent)
    x0, y0, x1, y1 = (float(c) for c in extent)
    return x0, y0, x1, y1


def keep_out_shapes(params: Params) -> np.ndarray:
    """(T, 3, 2) triangles of the scene file's ``[[keep_out.shapes]]`` boxes and discs."""
    parts = []
    for i, row in enumerate(params.keep_out.shapes):
        if row["shape"] == "box":
            if min(row["size"]) <= 0.0:
                raise ParameterError(f"keep_out.shapes[{i}].size", f"{list(row['size'])} has a side of 0 "
                                     "(valid: width and depth > 0 m)")
            parts.append(box_triangles(row["center"], row["size"], row["angle"]))
        else:
            if row["radius"] <= 0.0:
                raise ParameterError(f"keep_out.shapes[{i}].radius", "0 m draws no disc (valid: > 0 m)")
            parts.append(disc_triangles(row["center"], row["radius"]))
    return np.concatenate(parts) if parts else np.zeros((0, 3, 2))


def from_params(params: Params, load, extra: Paint | None = None, blender: bool = False) -> Paint | None:
    """The paint of a scene file's settings (``[paint]``, the species rows' ``density_map``,
    ``[[keep_out.shapes]]``), file maps read by ``load(path, setting name) -> values (ny, nx)``
    (``images.read_map``). ``extra``: maps and footprints from Blender (the terrain's vertex
    groups, a keep-out collection) that the file's settings do not name; a map named in both is
    taken from the settings. ``blender``: the caller reads Blender's sources (``extra``); without
    Blender a ``vertex_group:``, ``attribute:`` or ``image:`` map is refused, naming the setting.
    None when nothing is painted."""
    if not blender:
        for name, value in map_settings(params):
            if value.startswith(BLENDER_SOURCES):
                raise ParameterError(name, f"{value!r} is read from the terrain mesh or an image inside Blender, "
                                     "which this run (no Blender) does not have; valid here: a PNG file "
                                     "(save the painted map as a PNG), or render inside Blender")
    extent = None

    def raster(path: str, name: str):
        nonlocal extent
        if not path:
            return None
        if extent is None:
            extent = map_extent(params, params.paint.extent, "paint.extent")
        return Raster(load(path, name), extent, name)

    extra = extra or Paint()
    density = _is_file_map(params.paint.density) and raster(params.paint.density, "paint.density") or extra.density
    length = _is_file_map(params.paint.length) and raster(params.paint.length, "paint.length") or extra.length
    species = []
    for i, row in enumerate(params.species()):
        mine = extra.species[i] if i < len(extra.species) else None
        path = row.get("density_map", "")
        species.append(_is_file_map(path) and raster(path, f"blade.species[{i}].density_map") or mine)
    triangles = keep_out_shapes(params)
    if extra.keep_out is not None:
        triangles = np.concatenate([triangles, extra.keep_out.triangles])
    keep = KeepOut(triangles, params.keep_out.margin, params.keep_out.falloff) if len(triangles) else None
    paint = Paint(density=density or None, length=length or None, species=tuple(species), keep_out=keep)
    return None if paint.empty else paint


def map_settings(params: Params) -> list[tuple[str, str]]:
    """(setting, value) of every paint map setting that names something."""
    out = [("paint.density", params.paint.density), ("paint.length", params.paint.length)]
    out += [(f"blade.species[{i}].density_map", row.get("density_map", "")) for i, row in enumerate(params.species())]
    return [(name, value) for name, value in out if value]


def _is_file_map(value: str) -> bool:
    return bool(value) and not value.startswith(BLENDER_SOURCES)


EVERYWHERE = (-math.inf, -math.inf, math.inf, math.inf)


def changed_region(old: Paint | None, new: Paint | None, shapes: bool = False):
    """The box (x0, y0, x1, y1) in which ``new`` grows other blades than ``old`` (None: nothing
    changed). ``shapes``: only where the blades themselves differ (their length or species: the
    cells' representative blades, hence their sway), not merely which of them grow."""
    old, new = old or Paint(), new or Paint()
    boxes = [_raster_change(old.length, new.length)]
    rows = max(len(old.species), len(new.species))
    for k in range(rows):
        a = old.species[k] if k < len(old.species) else None
        b = new.species[k] if k < len(new.species) else None
        boxes.append(_raster_change(a, b))
    if not shapes:
        boxes.append(_raster_change(old.density, new.density))
        boxes.append(_keep_out_change(old.keep_out, new.keep_out))
    boxes = [b for b in boxes if b is not None]
    if not boxes:
        return None
    return (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes))


def _raster_change(a: Raster | None, b: Raster | None):
    if a is None and b is None:
        return None
    if a is None or b is None or a.values.shape != b.values.shape or a.extent != b.extent:
        return EVERYWHERE  # beyond its extent a map takes its edge values: it reaches everywhere
    if a.fingerprint() == b.fingerprint():
        return None
    ny, nx = a.values.shape
    rows, cols = np.nonzero(a.values != b.values)
    x0, y0, x1, y1 = a.extent
    px, py = (x1 - x0) / nx, (y1 - y0) / ny
    # a pixel's value reaches to its neighbours' centres (bilinear), and past the edge (clamped)
    left = -math.inf if cols.min() == 0 else x0 + (cols.min() - 0.5) * px
    right = math.inf if cols.max() == nx - 1 else x0 + (cols.max() + 1.5) * px
    bottom = -math.inf if rows.min() == 0 else y0 + (rows.min() - 0.5) * py
    top = math.inf if rows.max() == ny - 1 else y0 + (rows.max() + 1.5) * py
    return left, bottom, right, top


def _keep_out_change(a: KeepOut | None, b: KeepOut | None):
    if a is None and b is None:
        return None
    if a is not None and b is not None and len(a.triangles) == len(b.triangles) \
            and np.array_equal(a.triangles, b.triangles) and (a.margin, a.falloff) == (b.margin, b.falloff):
        return None
    boxes = [k.bounds() for k in (a, b) if k is not None and len(k.triangles)]
    if not boxes:
        return None
    return (min(x[0] for x in boxes), min(x[1] for x in boxes), max(x[2] for x in boxes), max(x[3] for x in boxes))
