"""The wind the grass feels, on a grid: what Blender's own physics (Hair Dynamics, Cloth Dynamics)
blow with.

Each frame the engine samples its wind (eq 12: the mean wind and its turbulence, eq 13's gusts or
vortex, the scene's force fields) at the points of a regular grid over the field's window of
blocks, at half the grass's height: exactly the wind the blades there are stepped with.
``bridge/wind_force.py`` writes the grid into a mesh (attributes ``wind`` and ``wind_speed``) that
the Windgrass Wind node group samples where the hair's or the cloth's points are (linearly between
grid points) and turns into a drag force. Numpy only.
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


def drag_force(wind: np.ndarray, velocity: np.ndarray, drag: float) -> np.ndarray:
    """The quadratic drag the Windgrass Wind node group applies to each point (its readable twin):
    F = drag |u| u with u = wind - velocity, the air's speed relative to the point (N, with
    ``drag`` in kg/m: half the air's density times the drag coefficient times the area a point
    stands for)."""
    u = np.asarray(wind, np.float64) - np.asarray(velocity, np.float64)
    return drag * np.linalg.norm(u, axis=-1, keepdims=True) * u
