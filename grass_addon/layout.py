"""The layout of a set of blocks (paper III): blades in cells, one card per cell, as flat arrays.

A ``FieldLayout`` holds the blocks a frame works on: the whole field (``build_layout``, small
fields and tests) or the window of blocks around the camera (``window_layout``). Its arrays are
the blocks' data (``blocks.py``, generated on demand) laid end to end: blade arrays block-major,
then cell, then slot, so the blades of local block ``i`` are one contiguous slice and every
block has the same number of blades: one mesh topology serves any block (see DEVELOPERS.md).
Cells of a whole-field layout are row-major over the field (``c = cy * cells_x + cx``); those of
a window are block-major (``block_cells`` maps either way).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .blocks import RNG_BLADES, RNG_CELLS, Block, BlockCache
from .grid import FieldGrid
from .schema import Params
from .terrain import Heightfield

__all__ = ["RNG_BLADES", "RNG_CELLS", "CellSet", "FieldLayout", "build_layout", "cell_set", "subset_layout",
           "window_layout"]


@dataclass(eq=False)
class FieldLayout:
    """Some blocks of a field (``block_ids``) as flat arrays; ``grid`` describes the whole field
    (its extent, cell and blade counts: ``layout.blocks_x`` and the like read it)."""

    params: Params
    grid: FieldGrid  # the whole field's block grid
    block_ids: np.ndarray  # (n_blocks,) int64 field-wide id of each local block
    block_cells: np.ndarray  # (n_blocks, cells_per_block**2) int32 flat cell ids
    block_bounds: np.ndarray  # (n_blocks, 4) float32 xmin, ymin, xmax, ymax
    cell_center: np.ndarray  # (n_cells, 2) float32
    # blades, block-major
    blade_root: np.ndarray
    blade_cell: np.ndarray
    blade_slot: np.ndarray
    blade_facing: np.ndarray
    blade_length: np.ndarray
    blade_width: np.ndarray
    blade_inclination: np.ndarray
    blade_shade: np.ndarray
    blade_species: np.ndarray
    blade_rest_tilt: np.ndarray
    blade_head: np.ndarray  # (n_blades,) float32 seed head width / stem width; 0: no head (meadow.py)
    blade_flower: np.ndarray  # (n_blades,) float32 flower width / stem width; 0: no flower
    blade_dry: np.ndarray  # (n_blades,) float32 how dry the tip is, 0..1
    # the representative blade of each cell, simulated by the solver (paper V.B)
    cell_length: np.ndarray
    cell_width: np.ndarray
    cell_root_stiffness: np.ndarray
    cell_rest_tilt: np.ndarray
    cell_facing: np.ndarray
    # cards (paper III.B)
    card_height: np.ndarray
    card_facing: np.ndarray
    card_shade: np.ndarray
    card_center: np.ndarray  # (n_cells, 2) float32: each card's foot, jittered inside its cell
    species_color: np.ndarray  # (n_species, 3) float32 linear RGB
    species_head_color: np.ndarray  # (n_species, 3) float32 linear RGB of its seed heads or flowers
    cell_ground: np.ndarray  # (n_cells,) float32 ground z at each cell centre (0 on flat ground)
    block_z_range: np.ndarray  # (n_blocks, 2) float32 lowest, highest ground (0, 0 on flat ground)
    terrain: Heightfield | None = None  # None = flat ground z = 0; blade_root z lies on it
    blade_ground_slope: np.ndarray | None = None  # (n_blades, 2) float32 dz/dx, dz/dy at each root; None: flat
    blade_alive: np.ndarray | None = None  # (n_blades,) bool: the blade grows (paint.py); None: all do
    cell_density: np.ndarray | None = None  # (n_cells,) float32 share of the cell's blades that grow

    # --- this set of blocks
    @property
    def n_blocks(self) -> int:
        return len(self.block_ids)

    @property
    def n_cells(self) -> int:
        return self.n_blocks * self.grid.cells_per_block_total

    @property
    def n_blades(self) -> int:
        return self.n_blocks * self.grid.blades_per_block

    # --- the whole field (its grid)
    blocks_x = property(lambda self: self.grid.blocks_x)
    blocks_y = property(lambda self: self.grid.blocks_y)
    cells_per_block = property(lambda self: self.grid.cells_per_block)
    cell_size = property(lambda self: self.grid.cell_size)
    segments = property(lambda self: self.grid.segments)
    blades_per_cell = property(lambda self: self.grid.blades_per_cell)
    cells_x = property(lambda self: self.grid.cells_x)
    cells_y = property(lambda self: self.grid.cells_y)
    cells_per_block_total = property(lambda self: self.grid.cells_per_block_total)
    blades_per_block = property(lambda self: self.grid.blades_per_block)
    origin = property(lambda self: self.grid.origin)
    size = property(lambda self: self.grid.size, doc="Field extent along X and Y in metres.")

    def retitled(self, params: Params, species_color: np.ndarray, species_head_color: np.ndarray) -> FieldLayout:
        """These blocks with ``params`` that change none of them (a wind, physics, LOD or look edit,
        ``edit_parts``) and the species' colours of ``params``: the arrays are shared, not copied."""
        return replace(self, params=params, species_color=species_color, species_head_color=species_head_color)

    def block_blades(self, block: int) -> slice:
        start = block * self.blades_per_block
        return slice(start, start + self.blades_per_block)


def _block_cells(blocks_x: int, blocks_y: int, cpb: int) -> np.ndarray:
    """Flat (row-major over the field) cell ids of every block, row-major inside the block."""
    cells_x = blocks_x * cpb
    by, bx = np.divmod(np.arange(blocks_x * blocks_y), blocks_x)
    ly, lx = np.divmod(np.arange(cpb * cpb), cpb)
    cy = by[:, None] * cpb + ly[None, :]
    cx = bx[:, None] * cpb + lx[None, :]
    return (cy * cells_x + cx).astype(np.int32)


_BLADE_ARRAYS = ("blade_root", "blade_facing", "blade_length", "blade_width", "blade_inclination",
                 "blade_shade", "blade_species", "blade_rest_tilt", "blade_head", "blade_flower",
                 "blade_dry")  # block after block
_CELL_ARRAYS = ("cell_center", "cell_ground", "cell_length", "cell_width", "cell_root_stiffness",
                "cell_rest_tilt", "cell_facing", "card_height", "card_facing", "card_shade",
                "card_center")


def _layout(params: Params, grid: FieldGrid, ids: np.ndarray, block_cells: np.ndarray, arrays: dict,
            species_colors: tuple, terrain, z_range: np.ndarray, slope) -> FieldLayout:
    """A FieldLayout of blocks ``ids`` whose blade and cell ``arrays`` are already in place."""
    num, P = grid.blades_per_cell, grid.cells_per_block_total
    nb = len(ids)
    return FieldLayout(
        params=params, grid=grid, block_ids=np.asarray(ids, dtype=np.int64), block_cells=block_cells,
        block_bounds=grid.block_bounds(ids).astype(np.float32),
        blade_cell=np.repeat(block_cells.ravel().astype(np.int32), num),
        blade_slot=np.tile(np.arange(num, dtype=np.int32), nb * P),
        species_color=species_colors[0], species_head_color=species_colors[1], terrain=terrain,
        block_z_range=np.ascontiguousarray(z_range, dtype=np.float32), blade_ground_slope=slope, **arrays)


def _assemble(params: Params, cache: BlockCache, ids: np.ndarray, blocks: list[Block],
              block_cells: np.ndarray) -> FieldLayout:
    """The layout of ``blocks`` (ids ``ids``) with their cells placed as ``block_cells`` says."""
    n = int(params.blade.segments)
    order = block_cells.ravel()

    def blades(name: str) -> np.ndarray:
        if not blocks:
            shape = {"blade_root": (0, 3), "blade_rest_tilt": (0, n)}.get(name, (0,))
            return np.zeros(shape, np.int16 if name == "blade_species" else np.float32)
        return np.ascontiguousarray(np.concatenate([getattr(b, name) for b in blocks]))

    def cells(name: str) -> np.ndarray:
        if not blocks:
            shape = {"cell_center": (0, 2), "card_center": (0, 2), "cell_rest_tilt": (0, n)}.get(name, (0,))
            return np.zeros(shape, np.float32)
        values = np.concatenate([getattr(b, name) for b in blocks])
        out = np.empty_like(values)
        out[order] = values
        return out

    arrays = {name: blades(name) for name in _BLADE_ARRAYS}
    arrays.update({name: cells(name) for name in _CELL_ARRAYS})
    if cache.paint is not None:  # which blades grow (paint.py)
        arrays["blade_alive"] = np.concatenate([b.blade_alive for b in blocks]) if blocks else np.zeros(0, bool)
        arrays["cell_density"] = cells("cell_density")
    slope = None if cache.terrain is None else blades("blade_ground_slope")
    z_range = np.stack([b.z_range for b in blocks]) if blocks else np.zeros((0, 2), np.float32)
    colors = (cache.species.color, cache.species.head_color)
    return _layout(params, cache.grid, ids, block_cells, arrays, colors, cache.terrain, z_range, slope)


def window_layout(cache: BlockCache, blocks) -> FieldLayout:
    """The layout of the blocks ``blocks`` (field-wide ids, in that order); cells block-major."""
    ids = np.asarray(blocks, dtype=np.int64).ravel()
    P = cache.grid.cells_per_block ** 2
    block_cells = np.arange(ids.size * P, dtype=np.int32).reshape(ids.size, P)
    return _assemble(cache.params, cache, ids, cache.get(ids), block_cells)


def build_layout(params: Params, terrain: Heightfield | None = None, cache: BlockCache | None = None) -> FieldLayout:
    """The whole field's layout (cells row-major over the field); ``terrain`` (a heightfield in
    the field's frame, None: flat ground) sets the height of every blade root and cell."""
    cache = cache if cache is not None else BlockCache(params, terrain, budget=1 << 62)
    grid = cache.grid
    ids = np.arange(grid.n_blocks, dtype=np.int64)
    block_cells = _block_cells(grid.blocks_x, grid.blocks_y, grid.cells_per_block)
    return _assemble(params, cache, ids, cache.get(ids), block_cells)


def subset_layout(layout, local_blocks):
    """The layout of some of ``layout``'s blocks (local ids, in that order); cells block-major (a
    ``CellSet``'s: the same cells of fewer blocks)."""
    local = np.asarray(local_blocks, dtype=np.int64).ravel()
    if isinstance(layout, CellSet):
        return layout.subset(local)
    P, bpb = layout.cells_per_block_total, layout.blades_per_block
    cells = layout.block_cells[local].ravel()
    blades = (local[:, None] * bpb + np.arange(bpb)).ravel()
    arrays = {name: getattr(layout, name)[blades] for name in _BLADE_ARRAYS}
    arrays.update({name: getattr(layout, name)[cells] for name in _CELL_ARRAYS})
    if layout.blade_alive is not None and layout.cell_density is not None:  # (painted: both, or neither)
        arrays["blade_alive"], arrays["cell_density"] = layout.blade_alive[blades], layout.cell_density[cells]
    slope = layout.blade_ground_slope
    block_cells = np.arange(local.size * P, dtype=np.int32).reshape(local.size, P)
    colors = (layout.species_color, layout.species_head_color)
    return _layout(layout.params, layout.grid, layout.block_ids[local], block_cells, arrays, colors,
                   layout.terrain, layout.block_z_range[local], None if slope is None else slope[blades])


_SOLVER_CELLS = ("cell_center", "cell_length", "cell_width", "cell_root_stiffness", "cell_rest_tilt", "cell_facing")


@dataclass(eq=False)
class CellSet:
    """Some cells of some blocks of a layout, with what the solver and the wind read of them
    (``far_sway.py``): each block's cells ``side`` x ``side``, one every ``step`` along each of its
    rows and columns (``step`` 1: all of them), block-major, each block's row-major."""

    params: Params
    grid: FieldGrid
    block_ids: np.ndarray  # (n_blocks,) int64 field-wide ids
    step: int
    cell_center: np.ndarray
    cell_length: np.ndarray
    cell_width: np.ndarray
    cell_root_stiffness: np.ndarray
    cell_rest_tilt: np.ndarray
    cell_facing: np.ndarray

    @property
    def side(self) -> int:
        return -(-self.grid.cells_per_block // self.step)

    cells_per_block = property(lambda self: self.side)  # (a block's cells are a side x side grid: wind.py)
    cells_x = cells_y = 0  # (never the whole field's grid)
    segments = property(lambda self: self.grid.segments)

    @property
    def n_blocks(self) -> int:
        return len(self.block_ids)

    @property
    def n_cells(self) -> int:
        return self.n_blocks * self.side * self.side

    @property
    def block_cells(self) -> np.ndarray:
        return np.arange(self.n_cells, dtype=np.int32).reshape(self.n_blocks, self.side * self.side)

    def subset(self, local: np.ndarray) -> CellSet:
        """The same cells of the local blocks ``local`` (in that order)."""
        cells = self.block_cells[local].ravel()
        return replace(self, block_ids=self.block_ids[local],
                       **{name: getattr(self, name)[cells] for name in _SOLVER_CELLS})


def cell_offsets(cells_per_block: int, step: int) -> np.ndarray:
    """Within a block (row-major), the cells one every ``step`` along its rows and columns."""
    picked = np.arange(0, cells_per_block, step)
    return (picked[:, None] * cells_per_block + picked[None, :]).ravel()


def cell_set(layout: FieldLayout, local_blocks, step: int = 1) -> CellSet:
    """``CellSet`` of ``layout``'s local blocks ``local_blocks`` (in that order), one cell every
    ``step`` along each block's rows and columns."""
    local = np.asarray(local_blocks, dtype=np.int64).ravel()
    cells = layout.block_cells[local][:, cell_offsets(layout.cells_per_block, step)].ravel()
    return CellSet(layout.params, layout.grid, layout.block_ids[local], int(step),
                   **{name: np.ascontiguousarray(getattr(layout, name)[cells]) for name in _SOLVER_CELLS})
