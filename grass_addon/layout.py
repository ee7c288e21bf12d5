"""The field's layout: blocks (patches) of square cells, blades in cells, one card per cell (paper III).

Everything here is computed once per parameter set. Blade arrays are ordered block-major, then cell
(row-major inside the block), then slot, so the blades of block ``b`` are one contiguous slice and every
block has the same number of blades: one mesh topology serves any block (see DEVELOPERS.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np

from . import blade
from .schema import Params
from .terrain import Heightfield, ground_z

# Purposes of the random streams: np.random.default_rng([seed, PURPOSE]).
RNG_BLADES = 1
RNG_CELLS = 2


@dataclass(eq=False)
class FieldLayout:
    params: Params
    blocks_x: int
    blocks_y: int
    cells_per_block: int
    cell_size: float
    segments: int
    blades_per_cell: int
    cells_x: int
    cells_y: int
    n_cells: int
    n_blocks: int
    cells_per_block_total: int
    blades_per_block: int
    n_blades: int
    origin: np.ndarray  # (2,) lower-left corner of the field; the field is centred on (0, 0)
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
    species_color: np.ndarray  # (n_species, 3) float32 linear RGB
    # terrain: None = flat ground z = 0; blade_root z lies on it
    terrain: Heightfield | None = None
    cell_ground: np.ndarray = dc_field(default=None)  # (n_cells,) float32 ground z at each cell centre
    block_z_range: np.ndarray = dc_field(default=None)  # (n_blocks, 2) float32 lowest, highest ground
    blade_ground_slope: np.ndarray | None = None  # (n_blades, 2) float32 dz/dx, dz/dy at each root

    @property
    def size(self) -> tuple[float, float]:
        """Field extent along X and Y in metres."""
        return self.cells_x * self.cell_size, self.cells_y * self.cell_size

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


def _species_arrays(params: Params) -> dict[str, np.ndarray]:
    rows = params.species()
    weights = np.array([r["weight"] for r in rows], dtype=np.float64)
    return {
        "p": weights / weights.sum(),
        "length": np.array([r["length"] for r in rows], dtype=np.float64),
        "length_variation": np.array([r["length_variation"] for r in rows], dtype=np.float64),
        "width": np.array([r["width"] for r in rows], dtype=np.float64),
        "stiffness": np.array([r["stiffness"] for r in rows], dtype=np.float64),
        "color": np.array([r["color"] for r in rows], dtype=np.float32).reshape(-1, 3),
    }


def _sample_blades(rng: np.random.Generator, count: int, params: Params, species: dict[str, np.ndarray]):
    """Species, length (l = l_base + lambda*N(0,1), kept positive), width, stiffness, alpha of `count` blades."""
    kind = rng.choice(len(species["p"]), size=count, p=species["p"]).astype(np.int16)
    base = species["length"][kind]
    # paper III.A (1): delta_l = lambda * N(0,1); a blade keeps at least 15 % of the reference length
    length = np.maximum(base + species["length_variation"][kind] * rng.standard_normal(count), 0.15 * base)
    width = species["width"][kind] * np.clip(1.0 + 0.12 * rng.standard_normal(count), 0.6, 1.4)
    stiffness = params.blade.root_stiffness * species["stiffness"][kind]
    inclination = np.radians(params.blade.inclination) * rng.random(count)  # random initial alpha
    return kind, length, width, stiffness, inclination


def _rest_tilt(params: Params, length, stiffness, inclination) -> np.ndarray:
    """Absolute rest tilt of each segment from eqs 1-6 (blade.py)."""
    n = params.blade.segments
    seg = length / n
    mu = blade.joint_stiffness(stiffness, seg, n, params.blade.stiffness_offset)  # eq 5
    theta = blade.rest_angles(inclination, seg, mu, params.blade.density)  # eqs 2-4, 6
    return blade.rest_tilt(inclination, theta)


def build_layout(params: Params, terrain: Heightfield | None = None) -> FieldLayout:
    """The layout of ``params``; ``terrain`` (a heightfield in the field's frame, None: flat
    ground) sets the height of every blade root and cell (the x/y layout does not change)."""
    f = params.field
    cpb, cs, num, n = f.cells_per_block, f.cell_size, f.blades_per_cell, params.blade.segments
    cells_x, cells_y = f.blocks_x * cpb, f.blocks_y * cpb
    n_cells, n_blocks = cells_x * cells_y, f.blocks_x * f.blocks_y
    origin = -0.5 * np.array([cells_x * cs, cells_y * cs])

    cy, cx = np.divmod(np.arange(n_cells), cells_x)
    cell_center = (origin + (np.stack([cx, cy], axis=1) + 0.5) * cs).astype(np.float32)
    block_cells = _block_cells(f.blocks_x, f.blocks_y, cpb)
    by, bx = np.divmod(np.arange(n_blocks), f.blocks_x)
    block_size = cpb * cs
    block_bounds = np.stack([origin[0] + bx * block_size, origin[1] + by * block_size,
                             origin[0] + (bx + 1) * block_size, origin[1] + (by + 1) * block_size],
                            axis=1).astype(np.float32)

    species = _species_arrays(params)
    rng = np.random.default_rng([f.seed, RNG_BLADES])
    n_blades = n_cells * num
    blade_cell = np.repeat(block_cells.ravel(), num).astype(np.int32)
    blade_slot = np.tile(np.arange(num, dtype=np.int32), n_cells)
    # paper III.A (2): random position inside the cell and random orientation
    offset = rng.random((n_blades, 2)) * cs - 0.5 * cs
    root = np.zeros((n_blades, 3), dtype=np.float32)
    root[:, :2] = cell_center[blade_cell] + offset
    root[:, 2] = ground_z(terrain, root[:, :2])  # rooted on the terrain surface
    cell_ground = ground_z(terrain, cell_center)
    if terrain is None:
        block_z_range = np.zeros((n_blocks, 2), np.float32)
    else:
        block_z_range = terrain.box_z_range(block_bounds)
    facing = (rng.random(n_blades) * 2.0 * np.pi).astype(np.float32)
    kind, length, width, stiffness, inclination = _sample_blades(rng, n_blades, params, species)
    shade = rng.random(n_blades).astype(np.float32)
    rest_tilt = _rest_tilt(params, length, stiffness, inclination)

    # The cell's representative blade (paper V.B: blades of a cell share the cell's bend and twist):
    # the mean of its blades, or a sampled virtual blade when cells hold no blades.
    cell_rng = np.random.default_rng([f.seed, RNG_CELLS])
    if num > 0:
        order = block_cells.ravel()

        def per_cell(values: np.ndarray) -> np.ndarray:
            out = np.empty((n_cells,) + values.shape[1:], dtype=np.float32)
            out[order] = values.reshape((n_cells, num) + values.shape[1:]).mean(axis=1)
            return out

        cell_length, cell_width = per_cell(length), per_cell(width)
        cell_stiffness, cell_rest_tilt = per_cell(stiffness), per_cell(rest_tilt)
    else:
        _, c_len, c_wid, c_stiff, c_inc = _sample_blades(cell_rng, n_cells, params, species)
        cell_length, cell_width = c_len.astype(np.float32), c_wid.astype(np.float32)
        cell_stiffness = c_stiff.astype(np.float32)
        cell_rest_tilt = _rest_tilt(params, c_len, c_stiff, c_inc)
    cell_facing = (cell_rng.random(n_cells) * 2.0 * np.pi).astype(np.float32)

    # paper III.B: card height = reference height + stochastic modifier; random orientation
    mean_length = float(np.dot(species["p"], species["length"]))
    mean_variation = float(np.dot(species["p"], species["length_variation"]))
    card_height = params.lod.card_height * np.maximum(
        cell_length + 0.5 * mean_variation * cell_rng.standard_normal(n_cells), 0.3 * mean_length)
    card_facing = cell_rng.random(n_cells) * np.pi
    card_shade = cell_rng.random(n_cells)

    f32 = np.float32
    return FieldLayout(
        params=params, blocks_x=f.blocks_x, blocks_y=f.blocks_y, cells_per_block=cpb, cell_size=cs,
        segments=n, blades_per_cell=num, cells_x=cells_x, cells_y=cells_y, n_cells=n_cells,
        n_blocks=n_blocks, cells_per_block_total=cpb * cpb, blades_per_block=cpb * cpb * num,
        n_blades=n_blades, origin=origin, block_cells=block_cells, block_bounds=block_bounds,
        cell_center=cell_center, blade_root=root, blade_cell=blade_cell, blade_slot=blade_slot,
        blade_facing=facing, blade_length=length.astype(f32), blade_width=width.astype(f32),
        blade_inclination=inclination.astype(f32), blade_shade=shade, blade_species=kind,
        blade_rest_tilt=np.ascontiguousarray(rest_tilt, dtype=f32),
        cell_length=cell_length, cell_width=cell_width, cell_root_stiffness=cell_stiffness,
        cell_rest_tilt=np.ascontiguousarray(cell_rest_tilt, dtype=f32), cell_facing=cell_facing,
        card_height=card_height.astype(f32), card_facing=card_facing.astype(f32),
        card_shade=card_shade.astype(f32), species_color=species["color"],
        terrain=terrain, cell_ground=np.ascontiguousarray(cell_ground, dtype=f32),
        block_z_range=np.ascontiguousarray(block_z_range, dtype=f32),
        blade_ground_slope=None if terrain is None else terrain.gradient(root[:, :2]),
    )
