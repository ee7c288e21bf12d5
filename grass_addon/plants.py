"""The artist's own plants as the cards draw them (issue #60): a collection's triangles, seen
from the side.

In Blender a species whose Own Plant is drawn as a plant is bent along every stem by the
Windgrass Heads node tree (``bridge/heads.py``): a point (x, y, z) of the source, H tall from its
lowest to its highest point, goes to the stem's centre line at arc share (z - z_min) / H, moved
x along the strip's side and y along its normal, times the stem's length / H. The cards stand for
the far blades (paper III.B), so their atlas (``atlas.py``) draws that species' stems as the
plant too, at their rest shape: ``PlantShape`` holds the source in those units (height 1) with
each triangle's colour, and ``draw`` rasterises it onto a card. Numpy only.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .schema import Params

MAX_TRIANGLES = 20_000  # a source's triangles drawn at most (the largest; a card is 256 pixels high)


@dataclass(frozen=True, eq=False)
class PlantShape:
    """A source in the stem's units: ``points`` (m, 3) float64 x, y, z / H with z from 0 (its
    lowest point) to 1 (its highest); ``triangles`` (t, 3) int64; ``colours`` (t, 3) float64
    linear RGB of each triangle."""

    points: np.ndarray
    triangles: np.ndarray
    colours: np.ndarray

    @staticmethod
    def of(points, triangles, colours) -> PlantShape:
        """From the source's own coordinates (m) as Blender places them."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        tri = np.asarray(triangles, np.int64).reshape(-1, 3)
        col = np.asarray(colours, np.float64).reshape(-1, 3)
        low, high = (float(p[:, 2].min()), float(p[:, 2].max())) if len(p) else (0.0, 1.0)
        height = max(high - low, 1e-6)
        p = np.column_stack([p[:, 0] / height, p[:, 1] / height, (p[:, 2] - low) / height])
        if len(tri) > MAX_TRIANGLES:
            a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
            keep = np.argsort(-np.linalg.norm(np.cross(b - a, c - a), axis=1))[:MAX_TRIANGLES]
            tri, col = tri[np.sort(keep)], col[np.sort(keep)]
        return PlantShape(p, tri, col)

    def mean_colour(self) -> tuple[float, float, float]:
        """Its colour as the far grass shows it: its triangles' colours weighed by their areas
        (linear RGB)."""
        if not len(self.triangles):
            return (0.0, 0.0, 0.0)
        a, b, c = (self.points[self.triangles[:, i]] for i in range(3))
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        weights = area if area.sum() > 0 else np.ones(len(area))
        r, g, bl = (weights @ self.colours) / weights.sum()
        return float(r), float(g), float(bl)

    def digest(self) -> str:
        h = hashlib.sha1()
        for array in (self.points, self.triangles, self.colours):
            h.update(np.ascontiguousarray(array).tobytes())
        return h.hexdigest()[:16]


@dataclass(frozen=True, eq=False)
class Plants:
    """The species drawn as an own plant: ``shapes`` ((species index, PlantShape), ...). Its
    ``repr`` is its contents' digest (what the kept looks are kept by: ``edit_parts``)."""

    shapes: tuple[tuple[int, PlantShape], ...] = ()

    def of_species(self, kind: int) -> PlantShape | None:
        return next((shape for k, shape in self.shapes if k == kind), None)

    def __repr__(self) -> str:
        return "Plants(" + ",".join(f"{k}:{shape.digest()}" for k, shape in self.shapes) + ")"

    def __bool__(self) -> bool:
        return bool(self.shapes)


def seen_far(params: Params, own: Plants | None) -> Params:
    """``params`` as the far grass shows them (the sward's colours, the ground under the cards):
    a species drawn as the artist's own plant takes that plant's colour (``mean_colour``); its
    blades' colour is never seen (its strips collapse under the plant)."""
    if not own:
        return params
    rows = [dict(row) for row in params.species()]
    for kind, shape in own.shapes:
        if kind < len(rows):
            rows[kind]["color"] = tuple(min(max(c, 0.0), 1.0) for c in shape.mean_colour())
    return params.replace({"blade.species": rows})


def draw(rgb: np.ndarray, alpha: np.ndarray, shape: PlantShape, u_root: float, across, along: np.ndarray,
         up: np.ndarray, scale_u: float, share: np.ndarray | None = None) -> None:
    """Draw ``shape`` onto a square card image (``rgb`` (size, size, 3), ``alpha`` (size, size),
    row 0 at the bottom), opaque, over what is there: stood on a stem whose rest centre line, in
    card units, runs through (``along``, ``up``) joint by joint from (0, 0) (``along`` across the
    card from the root at ``u_root``); a point at height share z sits on that line at arc share z,
    moved ``across`` . (x, y) across the card (the strip's side and normal along the card) times
    ``scale_u``, the stem's length over the card's width. ``share``: each joint's arc share of the
    stem (its segments' lengths; None: measured on the card). The card is periodic across, as its
    strips are."""
    size = alpha.shape[0]
    if not len(shape.triangles):
        return
    z = shape.points[:, 2]
    if share is None:
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(along), np.diff(up)))])
        share = arc / max(arc[-1], 1e-12)
    u = u_root + np.interp(z, share, along) + scale_u * (shape.points[:, :2] @ np.asarray(across, np.float64))
    v = np.interp(z, share, up)
    pix = np.column_stack([u * size, v * size])  # (m, 2) in pixels
    px, py, owner = _raster(pix[shape.triangles])
    px %= size
    inside = (py >= 0) & (py < size)
    px, py, owner = px[inside], py[inside], owner[inside]
    rgb[py, px] = shape.colours[owner]
    alpha[py, px] = 1.0


def _raster(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, triangle) of every pixel whose centre lies in one of the triangles ``corners``
    (t, 3, 2) in pixels, and of the pixel under each triangle's centroid (a triangle thinner than a
    pixel still shows), triangle by triangle: each tested over its bounding box (no Python loop)."""
    low = np.floor(corners.min(axis=1) - 0.5).astype(np.int64)
    high = np.ceil(corners.max(axis=1) - 0.5).astype(np.int64)
    width, height = high[:, 0] - low[:, 0] + 1, high[:, 1] - low[:, 1] + 1
    count = width * height
    owner = np.repeat(np.arange(len(corners)), count)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    x, y = low[owner, 0] + k % width[owner], low[owner, 1] + k // width[owner]
    cx, cy = x + 0.5, y + 0.5
    a, b, c = corners[owner, 0], corners[owner, 1], corners[owner, 2]

    def edge(p, q):  # which side of p -> q each centre lies (the cross product's sign)
        return (q[:, 0] - p[:, 0]) * (cy - p[:, 1]) - (q[:, 1] - p[:, 1]) * (cx - p[:, 0])

    e = np.stack([edge(a, b), edge(b, c), edge(c, a)])
    hit = (e >= 0.0).all(axis=0) | (e <= 0.0).all(axis=0)
    centroid = np.floor(corners.mean(axis=1)).astype(np.int64)
    return (np.concatenate([x[hit], centroid[:, 0]]), np.concatenate([y[hit], centroid[:, 1]]),
            np.concatenate([owner[hit], np.arange(len(corners))]))
