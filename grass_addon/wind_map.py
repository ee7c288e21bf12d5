"""The wind the grass feels, on a grid: what Blender's own physics (Hair Dynamics, Cloth Dynamics)
blow with.

Each frame the engine samples its wind (eq 12: the mean wind and its turbulence, eq 13's gusts or
vortex, the scene's force fields) at the points of a regular grid over the field's window of
blocks, at half the grass's height: exactly the wind the blades there are stepped with.
``bridge/wind_force.py`` writes the grid into a mesh (attributes ``wind`` and ``wind_speed``) that
the Windgrass Wind node group samples where the hair's or the cloth's points are (linearly between
grid points) and turns into a drag force.

The same grid carries what an artist's own node trees read of the field (``FieldMap``, issue
#60): the grass's standing height, how far the wind and colliders bend it (eq 33's omega), how flat
colliders trampled it, where its tops are (eq 34) and which species grows there, each the mean
(the most common) of the simulated cells nearest each point. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_SIDE = 64  # grid points along a side at most (4,096 points: a fraction of a millisecond a frame)
MIN_SPACING = 0.25  # m between grid points at least (the turbulence's lattice is metres wide)


@dataclass(frozen=True)
class MapGrid:
    """A regular grid of ``nx`` by ``ny`` points ``spacing`` apart from (x0, y0), row by row (x
    fastest)."""

    x0: float
    y0: float
    spacing: float
    nx: int
    ny: int

    @property
    def count(self) -> int:
        return self.nx * self.ny

    def points(self) -> np.ndarray:
        """(count, 2) float64 x, y of the points."""
        xs = self.x0 + self.spacing * np.arange(self.nx)
        ys = self.y0 + self.spacing * np.arange(self.ny)
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel()])

    def quads(self) -> np.ndarray:
        """(count of cells, 4) int32 corner indices of each grid cell, counter-clockwise seen from
        above (so the mesh's faces look up)."""
        i, j = np.meshgrid(np.arange(self.nx - 1), np.arange(self.ny - 1))
        a = (j * self.nx + i).ravel()
        return np.column_stack([a, a + 1, a + 1 + self.nx, a + self.nx]).astype(np.int32)


def map_grid(bounds) -> MapGrid:
    """The grid over ``bounds`` (xmin, ymin, xmax, ymax, m) and one spacing beyond each side (a
    point just past the field's edge reads the wind there, not its edge's): at most ``MAX_SIDE``
    points a side, at least ``MIN_SPACING`` apart."""
    xmin, ymin, xmax, ymax = (float(v) for v in bounds)
    span = max(xmax - xmin, ymax - ymin, MIN_SPACING)
    spacing = max(span / (MAX_SIDE - 3), MIN_SPACING)
    nx = min(int(np.ceil((xmax - xmin) / spacing)) + 3, MAX_SIDE)
    ny = min(int(np.ceil((ymax - ymin) / spacing)) + 3, MAX_SIDE)
    return MapGrid(xmin - spacing, ymin - spacing, spacing, max(nx, 2), max(ny, 2))


@dataclass(frozen=True)
class FieldMap:
    """The field at one frame on a ``MapGrid``, per point (the field's frame, metres):

    ground (count,) the ground's height; wind (count, 2) m/s; height (count,) how high the
    grass's tops stand at rest (its cells' tallest blades: their cards' height; 0 where none
    grows); bend (count,) rad, how far the wind and colliders bend it from its rest shape (eq
    33's omega, the sum of its segments' bends); flat (count,) 0..1, how flat colliders trampled
    it; tip (count, 3) where its tops are (eq 34's card top M'); species (count,) int32, the
    species of most of its blades (-1: none grows). Each is the mean over the simulated cells
    nearest the point; points beyond them read 0 (tip: the ground)."""

    grid: MapGrid
    ground: np.ndarray
    wind: np.ndarray
    height: np.ndarray
    bend: np.ndarray
    flat: np.ndarray
    tip: np.ndarray
    species: np.ndarray


def nearest_points(grid: MapGrid, xy) -> np.ndarray:
    """(m,) int64 index of the grid point nearest each of the points ``xy`` (m, 2) (clamped)."""
    xy = np.asarray(xy, np.float64)
    i = np.clip(np.rint((xy[:, 0] - grid.x0) / grid.spacing), 0, grid.nx - 1).astype(np.int64)
    j = np.clip(np.rint((xy[:, 1] - grid.y0) / grid.spacing), 0, grid.ny - 1).astype(np.int64)
    return j * grid.nx + i


def point_mean(grid: MapGrid, at: np.ndarray, values: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Per grid point the ``weight``-ed mean of ``values`` (m,) or (m, k) of the items nearest it
    (``at``: their points); 0 where none is."""
    w = np.bincount(at, weight, minlength=grid.count)
    values = np.asarray(values, np.float64)
    cols = values.reshape(len(at), -1)
    sums = np.stack([np.bincount(at, cols[:, k] * weight, minlength=grid.count) for k in range(cols.shape[1])], -1)
    mean = sums / np.maximum(w, 1e-12)[:, None]
    return mean.reshape((grid.count,) + values.shape[1:])


def most_common(grid: MapGrid, at: np.ndarray, kinds: np.ndarray, n_kinds: int) -> np.ndarray:
    """(count,) int32 per grid point the kind most of the items nearest it are; -1 where none is."""
    counts = np.bincount(at * n_kinds + kinds, minlength=grid.count * n_kinds).reshape(grid.count, n_kinds)
    return np.where(counts.any(axis=1), counts.argmax(axis=1), -1).astype(np.int32)


def drag_force(wind: np.ndarray, velocity: np.ndarray, drag: float) -> np.ndarray:
    """The quadratic drag the Windgrass Wind node group applies to each point (its readable twin):
    F = drag |u| u with u = wind - velocity, the air's speed relative to the point (N, with
    ``drag`` in kg/m: half the air's density times the drag coefficient times the area a point
    stands for)."""
    u = np.asarray(wind, np.float64) - np.asarray(velocity, np.float64)
    return drag * np.linalg.norm(u, axis=-1, keepdims=True) * u
