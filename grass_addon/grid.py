"""The field's grid (paper III): blocks of square cells holding blades; its extent and counts.

The one place where a field's size, cell and blade counts are computed from its parameters: a
``FieldGrid`` is a few numbers (no per-block arrays), so fields of any size cost nothing to
describe. Block ``b = by * blocks_x + bx``; cell ``(cx, cy)`` of the field lies in block
``(cx // cells_per_block, cy // cells_per_block)``; the field is centred on the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .schema import Params


@dataclass(frozen=True)
class FieldGrid:
    """The field's block grid: block ``b = by * blocks_x + bx``; cell ``(cx, cy)`` of the field
    lies in block ``(cx // cpb, cy // cpb)``. The field is centred on the origin."""

    blocks_x: int
    blocks_y: int
    cells_per_block: int
    cell_size: float
    blades_per_cell: int = 0
    segments: int = 5

    @staticmethod
    def blocks_covering(extent: tuple[float, float], block_edge: float, most: int) -> tuple[int, int]:
        """(blocks_x, blocks_y) whose blocks of edge ``block_edge`` cover ``extent`` (x, y metres):
        the fewest whole blocks that reach its edges (issue #63: rounded to the nearest, a rim of up
        to half a block stayed bare), at least one each way, at most ``most`` in all (both counts
        shrunk alike, the shape kept: then they cover less)."""
        bx, by = (max(1, math.ceil(e / block_edge - 1e-6)) for e in extent)
        if bx * by > most:
            shrink = math.sqrt(most / (bx * by))
            bx, by = max(1, int(bx * shrink)), max(1, int(by * shrink))
        return bx, by

    @classmethod
    def of(cls, params: Params) -> FieldGrid:
        f = params.field
        return cls(int(f.blocks_x), int(f.blocks_y), int(f.cells_per_block), float(f.cell_size),
                   int(f.blades_per_cell), int(params.blade.segments))

    @property
    def block_size(self) -> float:
        return self.cells_per_block * self.cell_size

    @property
    def n_blocks(self) -> int:
        return self.blocks_x * self.blocks_y

    @property
    def cells_per_block_total(self) -> int:
        """Cells in one block."""
        return self.cells_per_block ** 2

    @property
    def blades_per_block(self) -> int:
        return self.cells_per_block_total * self.blades_per_cell

    @property
    def n_cells(self) -> int:
        """Cells of the whole field."""
        return self.n_blocks * self.cells_per_block_total

    @property
    def n_blades(self) -> int:
        """Blades of the whole field."""
        return self.n_cells * self.blades_per_cell

    @property
    def cells_x(self) -> int:
        return self.blocks_x * self.cells_per_block

    @property
    def cells_y(self) -> int:
        return self.blocks_y * self.cells_per_block

    @property
    def size(self) -> tuple[float, float]:
        return self.cells_x * self.cell_size, self.cells_y * self.cell_size

    @property
    def origin(self) -> np.ndarray:
        """(2,) lower-left corner of the field."""
        return -0.5 * np.array(self.size)

    def block_xy(self, blocks) -> tuple[np.ndarray, np.ndarray]:
        """(bx, by) int64 of block ids."""
        by, bx = np.divmod(np.asarray(blocks, dtype=np.int64), self.blocks_x)
        return bx, by

    def block_bounds(self, blocks) -> np.ndarray:
        """(m, 4) float64 xmin, ymin, xmax, ymax of each block."""
        bx, by = self.block_xy(blocks)
        o, s = self.origin, self.block_size
        return np.stack([o[0] + bx * s, o[1] + by * s, o[0] + (bx + 1) * s, o[1] + (by + 1) * s], axis=1)

    def blocks_near(self, xy, radius: float) -> np.ndarray:
        """Ids (int64, ascending) of the blocks whose rectangle comes within ``radius`` of the
        ground point ``xy``: only the square of blocks around it is looked at."""
        o, s = self.origin, self.block_size
        lo = np.floor((np.asarray(xy, dtype=np.float64) - radius - o) / s).astype(np.int64)
        hi = np.floor((np.asarray(xy, dtype=np.float64) + radius - o) / s).astype(np.int64)
        bx = np.arange(max(lo[0], 0), min(hi[0], self.blocks_x - 1) + 1, dtype=np.int64)
        by = np.arange(max(lo[1], 0), min(hi[1], self.blocks_y - 1) + 1, dtype=np.int64)
        if bx.size == 0 or by.size == 0:
            return np.zeros(0, np.int64)
        ids = (by[:, None] * self.blocks_x + bx[None, :]).ravel()
        b = self.block_bounds(ids)
        nx = np.clip(xy[0], b[:, 0], b[:, 2]) - xy[0]
        ny = np.clip(xy[1], b[:, 1], b[:, 3]) - xy[1]
        return ids[nx * nx + ny * ny <= radius * radius]

    def cell_centers(self, block: int) -> np.ndarray:
        """(cpb**2, 2) float64 centres of a block's cells, row-major inside the block."""
        cpb = self.cells_per_block
        bx, by = self.block_xy(block)
        ly, lx = np.divmod(np.arange(cpb * cpb), cpb)
        cx, cy = int(bx) * cpb + lx, int(by) * cpb + ly
        return self.origin + (np.stack([cx, cy], axis=1) + 0.5) * self.cell_size
