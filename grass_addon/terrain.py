"""Terrain: the ground height under the field as a regular heightfield (numpy only, no bpy).

The paper grows its grass on flat ground; Windgrass can root the blades on a mesh. The bridge samples
the mesh at the points of a regular grid over the field (``grid_for``: one sample per cell corner,
coarser for very large fields) and hands the heights to the core as a ``Heightfield``. Between
samples the height is bilinear, so a plane (any tilt) is reproduced exactly. ``None`` everywhere
means flat ground, z = 0.

Coordinates are the field's frame (DEVELOPERS.md: X/Y in the ground plane, the field centred on
the origin); heights are metres along Z in that frame.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from .errors import ParameterError
from .grid import FieldGrid
from .schema import Params

# At most this many heightfield cells along a side: a 1024 x 1024-cell field is sampled every
# 4 cells (the bridge ray-casts once per sample at build time, and the ground mesh has one quad
# per heightfield cell).
MAX_GRID_CELLS = 256


class Heightfield:
    """Ground heights on a regular grid: sample (i, j) lies at origin_xy + spacing * (i, j).

    heights: (ny + 1, nx + 1) float32, row j along Y, column i along X; nx, ny >= 1.
    """

    def __init__(self, origin_xy, spacing: float, heights, rise: float = 0.0):
        self.rise = float(rise)  # how far the mesh it samples rises above it at most (``surface_rise``)
        self.origin_xy = np.asarray(origin_xy, dtype=np.float64).reshape(2)
        self.spacing = float(spacing)
        self.heights = np.ascontiguousarray(heights, dtype=np.float32)
        if not (self.spacing > 0.0 and math.isfinite(self.spacing)):
            raise ParameterError("terrain", f"heightfield spacing {spacing!r} must be a positive number")
        if self.heights.ndim != 2 or min(self.heights.shape) < 2:
            raise ParameterError("terrain", f"heightfield needs at least 2 x 2 samples, got shape {self.heights.shape}")
        if not np.all(np.isfinite(self.heights)):
            raise ParameterError("terrain", "heightfield heights must be finite")
        self.heights.setflags(write=False)

    @property
    def nx(self) -> int:
        return self.heights.shape[1] - 1

    @property
    def ny(self) -> int:
        return self.heights.shape[0] - 1

    @classmethod
    def flat(cls, origin_xy=(0.0, 0.0), spacing: float = 1.0, nx: int = 1, ny: int = 1) -> Heightfield:
        """Flat ground z = 0 (the same as no terrain)."""
        return cls(origin_xy, spacing, np.zeros((ny + 1, nx + 1), np.float32))

    def points(self) -> np.ndarray:
        """(ny + 1, nx + 1, 2) float64 XY of every sample."""
        return grid_points(self.origin_xy, self.spacing, self.nx, self.ny)

    def _cell(self, xy):
        """(i, j, fu, fv): the grid cell holding each point (clamped to the grid) and the point's
        fractions across it."""
        xy = np.asarray(xy, dtype=np.float64)
        u = np.clip((xy[..., 0] - self.origin_xy[0]) / self.spacing, 0.0, self.nx)
        v = np.clip((xy[..., 1] - self.origin_xy[1]) / self.spacing, 0.0, self.ny)
        i = np.minimum(np.floor(u), self.nx - 1).astype(np.intp)
        j = np.minimum(np.floor(v), self.ny - 1).astype(np.intp)
        return i, j, u - i, v - j

    def sample(self, xy) -> np.ndarray:
        """Bilinear height at points xy (..., 2) -> (...) float32; clamped to the grid outside it."""
        i, j, fu, fv = self._cell(xy)
        h = self.heights
        z00, z10 = h[j, i].astype(np.float64), h[j, i + 1].astype(np.float64)
        z01, z11 = h[j + 1, i].astype(np.float64), h[j + 1, i + 1].astype(np.float64)
        low = z00 + (z10 - z00) * fu
        high = z01 + (z11 - z01) * fu
        return (low + (high - low) * fv).astype(np.float32)

    def gradient(self, xy) -> np.ndarray:
        """(..., 2) float32 slope dz/dx, dz/dy of the bilinear surface at points xy (that of the
        nearest grid cell outside the grid)."""
        i, j, fu, fv = self._cell(xy)
        h = self.heights.astype(np.float64)
        z00, z10, z01, z11 = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
        dx = ((z10 - z00) * (1.0 - fv) + (z11 - z01) * fv) / self.spacing
        dy = ((z01 - z00) * (1.0 - fu) + (z11 - z10) * fu) / self.spacing
        return np.stack([dx, dy], axis=-1).astype(np.float32)

    def box_z_range(self, bounds) -> np.ndarray:
        """(m, 2) float32 lowest and highest ground over each rectangle (m, 4) xmin, ymin, xmax, ymax.

        The bilinear surface of a grid cell stays between its corner heights, so the range of the
        samples of every grid cell a rectangle touches bounds the ground over it (conservative).
        """
        b = np.asarray(bounds, dtype=np.float64).reshape(-1, 4)
        s, (ox, oy) = self.spacing, self.origin_xy
        # grid cells touched: columns i0..i1-1, rows j0..j1-1 (clamped: outside, the edge holds)
        i0 = np.clip(np.floor((b[:, 0] - ox) / s), 0, self.nx - 1).astype(np.intp)
        i1 = np.clip(np.ceil((b[:, 2] - ox) / s), i0 + 1, self.nx).astype(np.intp)
        j0 = np.clip(np.floor((b[:, 1] - oy) / s), 0, self.ny - 1).astype(np.intp)
        j1 = np.clip(np.ceil((b[:, 3] - oy) / s), j0 + 1, self.ny).astype(np.intp)
        h = self.heights
        # Distinct column spans and row spans are few (one per block column / row): reduce the
        # samples over each column span, then each of those over each row span.
        col_keys, col_of = np.unique(np.stack([i0, i1], 1), axis=0, return_inverse=True)
        row_keys, row_of = np.unique(np.stack([j0, j1], 1), axis=0, return_inverse=True)
        lo = np.stack([h[:, a:c + 1].min(axis=1) for a, c in col_keys])  # (n_col_spans, ny + 1)
        hi = np.stack([h[:, a:c + 1].max(axis=1) for a, c in col_keys])
        lo = np.stack([lo[:, d:e + 1].min(axis=1) for d, e in row_keys], axis=1)  # (cols, rows)
        hi = np.stack([hi[:, d:e + 1].max(axis=1) for d, e in row_keys], axis=1)
        col_of, row_of = col_of.ravel(), row_of.ravel()
        return np.stack([lo[col_of, row_of], hi[col_of, row_of]], axis=1).astype(np.float32)

    def fingerprint(self) -> str:
        """Hash of the grid and the heights (the runtime rebuilds when it changes)."""
        h = hashlib.sha1()
        h.update(np.asarray([*self.origin_xy, self.spacing], np.float64).tobytes())
        h.update(np.asarray(self.heights.shape, np.int64).tobytes())
        h.update(self.heights.tobytes())
        return h.hexdigest()


def grid_points(origin_xy, spacing: float, nx: int, ny: int) -> np.ndarray:
    """(ny + 1, nx + 1, 2) float64 XY of a grid's samples, row-major over Y then X."""
    ox, oy = np.asarray(origin_xy, dtype=np.float64).reshape(2)
    xs = ox + spacing * np.arange(nx + 1)
    ys = oy + spacing * np.arange(ny + 1)
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx, gy], axis=-1)


def grid_for(params: Params, max_cells: int = MAX_GRID_CELLS) -> tuple[np.ndarray, float, int, int]:
    """(origin_xy, spacing, nx, ny) of the heightfield grid over the field of ``params``.

    One sample per cell corner (spacing = cell size); a field wider than ``max_cells`` cells is
    sampled every ``step`` cells. The grid covers the whole field (it may reach past the far edge
    by less than one spacing).
    """
    grid = FieldGrid.of(params)
    cells_x, cells_y = grid.cells_x, grid.cells_y
    step = max(1, math.ceil(max(cells_x, cells_y) / max_cells))
    spacing = grid.cell_size * step
    origin = grid.origin
    return origin, spacing, math.ceil(cells_x / step), math.ceil(cells_y / step)


def ground_z(terrain: Heightfield | None, xy) -> np.ndarray:
    """Ground height at xy (..., 2) -> (...) float32; zeros on flat ground (terrain None)."""
    xy = np.asarray(xy)
    if terrain is None:
        return np.zeros(xy.shape[:-1], np.float32)
    return terrain.sample(xy)


def surface_rise(triangles, heightfield: Heightfield) -> float:
    """How far a mesh's surface (``triangles`` (T, 3, 3) in the field's frame) rises above the
    bilinear heightfield sampled from it, at most, over the heightfield's extent: points along each
    edge (a piecewise-flat mesh is highest above a smooth sampling along its ridges), 0 if nowhere.
    A ground drawn over the mesh lifted this much more hides it (a ridge 2 mm up showed the
    terrain's material through the grass as dashed lines, issue #37)."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    if len(tris) == 0:
        return 0.0
    edges = np.stack([tris, np.roll(tris, -1, axis=1)], axis=2).reshape(-1, 2, 3)  # (E, 2, 3)
    t = np.linspace(0.0, 1.0, 5)[None, :, None]
    points = (edges[:, :1] * (1.0 - t) + edges[:, 1:] * t).reshape(-1, 3)
    lo = heightfield.origin_xy
    hi = lo + heightfield.spacing * np.array([heightfield.nx, heightfield.ny])
    inside = np.all((points[:, :2] >= lo) & (points[:, :2] <= hi), axis=1)
    if not inside.any():
        return 0.0
    points = points[inside]
    return float(max(0.0, np.max(points[:, 2] - heightfield.sample(points[:, :2]))))


def fill_missing(heights, hit, fallback: float | None = None) -> np.ndarray:
    """Heights where ``hit`` is False (rays that missed the mesh) take the height of the nearest
    hit sample (grown ring by ring, 8-neighbourhood); with no hit at all, ``fallback`` (or 0).

    heights, hit: (ny + 1, nx + 1). Returns a new float32 array.
    """
    z = np.array(heights, dtype=np.float64)
    known = np.array(hit, dtype=bool)
    if not known.any():
        return np.full(z.shape, 0.0 if fallback is None else fallback, np.float32)
    z[~known] = 0.0
    while not known.all():
        # Mean of the known neighbours of each unknown sample adjacent to the known region.
        total = np.zeros_like(z)
        count = np.zeros(z.shape, np.int32)
        pz = np.pad(np.where(known, z, 0.0), 1)
        pk = np.pad(known, 1)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                sl = (slice(1 + dy, pz.shape[0] - 1 + dy), slice(1 + dx, pz.shape[1] - 1 + dx))
                total += pz[sl]
                count += pk[sl]
        grow = ~known & (count > 0)
        z[grow] = total[grow] / count[grow]
        known |= grow
    return z.astype(np.float32)


def drape(triangles, origin_xy, spacing: float, nx: int, ny: int,
          chunk_pairs: int = 1 << 21, corner_values=None):
    """Heights of a triangle mesh at the grid's samples, as a ray cast straight down from above
    would find them: the highest surface over each sample (the top of the terrain).

    triangles: (T, 3, 3) vertex positions in the field's frame. Returns (heights, hit), both
    (ny + 1, nx + 1): float32 heights (0 where nothing was hit) and bool hit. Vectorised: every
    triangle is tested against the samples inside its XY bounding box (barycentric coordinates),
    in chunks of at most ``chunk_pairs`` (triangle, sample) pairs. ``corner_values`` (T, 3, k):
    values at each triangle's corners (a vertex group's weights, a UV map); then (heights, hit,
    values) with values (ny + 1, nx + 1, k) interpolated on the top surface at each sample.
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    ox, oy = np.asarray(origin_xy, dtype=np.float64).reshape(2)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]  # twice the signed XY area
    scale = np.maximum(np.abs(e1[:, :2]).max(axis=1), np.abs(e2[:, :2]).max(axis=1))
    keep = np.abs(det) > 1e-12 * np.maximum(scale * scale, 1e-30)  # seen edge-on from above: no area
    tri, a, e1, e2, det = tri[keep], a[keep], e1[keep], e2[keep], det[keep]
    if corner_values is not None:
        corner_values = np.asarray(corner_values, dtype=np.float64)
        corner_values = corner_values.reshape(corner_values.shape[0], 3, -1)[keep]
        picked = np.zeros(((ny + 1) * (nx + 1), corner_values.shape[-1]))
    best = np.full((ny + 1) * (nx + 1), -np.inf)
    if len(tri):
        eps = 1e-9
        u = (tri[:, :, 0] - ox) / spacing
        v = (tri[:, :, 1] - oy) / spacing
        i0 = np.clip(np.ceil(u.min(axis=1) - eps), 0, nx + 1).astype(np.int64)
        i1 = np.clip(np.floor(u.max(axis=1) + eps), -1, nx).astype(np.int64)
        j0 = np.clip(np.ceil(v.min(axis=1) - eps), 0, ny + 1).astype(np.int64)
        j1 = np.clip(np.floor(v.max(axis=1) + eps), -1, ny).astype(np.int64)
        width = np.maximum(i1 - i0 + 1, 0)
        counts = width * np.maximum(j1 - j0 + 1, 0)
        ends = np.cumsum(counts)
        start = 0
        while start < len(tri):
            # the next triangles up to chunk_pairs pairs (at least one triangle)
            limit = (ends[start - 1] if start else 0) + chunk_pairs
            stop = max(start + 1, int(np.searchsorted(ends, limit, side="right")))
            idx = np.arange(start, stop)
            cnt = counts[idx]
            total = int(cnt.sum())
            start = stop
            if total == 0:
                continue
            t = np.repeat(idx, cnt)
            local = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            di, dj = np.divmod(local, width[t])[::-1]
            pi, pj = i0[t] + di, j0[t] + dj
            px, py = ox + spacing * pi - a[t, 0], oy + spacing * pj - a[t, 1]
            # barycentric (l1 along e1, l2 along e2): p - a = l1 e1 + l2 e2 in XY
            l1 = (px * e2[t, 1] - e2[t, 0] * py) / det[t]
            l2 = (e1[t, 0] * py - px * e1[t, 1]) / det[t]
            inside = (l1 >= -eps) & (l2 >= -eps) & (l1 + l2 <= 1.0 + eps)
            z = a[t, 2] + l1 * e1[t, 2] + l2 * e2[t, 2]
            flat_id = pj * (nx + 1) + pi
            np.maximum.at(best, flat_id[inside], z[inside])
            if corner_values is not None:  # the values of the highest surface found so far
                sel = np.flatnonzero(inside)
                order = sel[np.argsort(z[sel], kind="stable")]  # ascending: the highest written last
                order = order[z[order] >= best[flat_id[order]]]
                cv = corner_values[t[order]]
                w1, w2 = l1[order, None], l2[order, None]
                picked[flat_id[order]] = cv[:, 0] + w1 * (cv[:, 1] - cv[:, 0]) + w2 * (cv[:, 2] - cv[:, 0])
    hit = np.isfinite(best)
    heights = np.where(hit, best, 0.0).astype(np.float32).reshape(ny + 1, nx + 1)
    if corner_values is not None:
        return heights, hit.reshape(ny + 1, nx + 1), picked.reshape(ny + 1, nx + 1, -1)
    return heights, hit.reshape(ny + 1, nx + 1)


def from_heightmap(values, extent, height: float, params: Params, name: str = "terrain.heightmap") -> Heightfield:
    """The heightfield of a greyscale heightmap (values 0..1, row 0 at y0) lying over ``extent``
    ([x0, y0, x1, y1] in the field's frame), white ``height`` metres above black, sampled at the
    field's heightfield grid (``grid_for``; bilinear between pixel centres)."""
    from .paint import Raster

    origin, spacing, nx, ny = grid_for(params)
    heights = Raster(values, extent, name).sample(grid_points(origin, spacing, nx, ny)) * float(height)
    return Heightfield(origin, spacing, heights.astype(np.float32))


def from_params(params: Params, load) -> Heightfield | None:
    """The scene file's ``[terrain]`` heightmap (``load(path, setting name)`` reads it,
    ``images.read_map``), or None for flat ground."""
    t = params.terrain
    if not t.heightmap:
        return None
    from .paint import map_extent

    extent = map_extent(params, t.extent, "terrain.extent")
    return from_heightmap(load(t.heightmap, "terrain.heightmap"), extent, t.height, params)
