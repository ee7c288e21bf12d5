"""Blocks on demand: the field's grid, one block's blades and cells, and a bounded cache (paper III).

A field of any size is a grid of ``blocks_x * blocks_y`` square blocks (``FieldGrid``: a few
numbers, no per-block arrays). Everything inside a block (blade roots, species, lengths, rest
shapes of eqs 1-6, the representative blade of each cell, the cards) is a pure function of
(parameters, seed, block id): ``make_block`` draws it from random streams keyed by the block id,
so a block is the same whenever and wherever it is generated. ``BlockCache`` keeps recently used
blocks within a memory budget.
"""

from __future__ import annotations

import copy
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from . import blade, edit_parts, heads, meadow
from .errors import ParameterError
from .grid import FieldGrid
from .paint import MIN_LENGTH_SCALE, Paint
from .schema import Params
from .terrain import Heightfield, ground_z

# Purposes of the random streams: np.random.default_rng([seed, PURPOSE, block id]).
RNG_BLADES = 1
RNG_CELLS = 2
MIN_BLADE_LENGTH = 1e-3  # m: a blade mown shorter is drawn this long (it does not grow, paint.py)
DEFAULT_CACHE_BYTES = 1 << 30  # the block cache's budget unless the caller sets one
MADE_TOGETHER = 16  # blocks grown and given their rest shapes in one pass (make_blocks)


@dataclass(eq=False)
class Block:
    """One block's blades (cell-major, then slot) and cells (row-major inside the block)."""

    blade_root: np.ndarray  # (B, 3) float32
    blade_facing: np.ndarray
    blade_length: np.ndarray
    blade_width: np.ndarray
    blade_inclination: np.ndarray
    blade_shade: np.ndarray
    blade_species: np.ndarray  # (B,) int16
    blade_head: np.ndarray  # (B,) float32: seed head width / stem width at the last joint but one; 0: none
    blade_flower: np.ndarray  # (B,) float32: flower width / stem width at the tip; 0: none
    blade_dry: np.ndarray  # (B,) float32: how dry its tip is, 0..1 (meadow.py)
    blade_rest_tilt: np.ndarray  # (B, n)
    blade_ground_slope: np.ndarray | None  # (B, 2) or None on flat ground
    cell_center: np.ndarray  # (P, 2) float32
    cell_ground: np.ndarray
    cell_length: np.ndarray
    cell_width: np.ndarray
    cell_root_stiffness: np.ndarray
    cell_rest_tilt: np.ndarray  # (P, n)
    cell_facing: np.ndarray
    card_height: np.ndarray
    card_facing: np.ndarray
    card_shade: np.ndarray
    card_center: np.ndarray  # (P, 2) float32: the card's foot, jittered inside its cell
    z_range: np.ndarray  # (2,) lowest, highest ground
    blade_alive: np.ndarray | None = None  # (B,) bool: the blade grows (paint); None: every blade
    cell_density: np.ndarray | None = None  # (P,) float32: share of the cell's blades that grow
    # (B,) float64 each blade's length and width as grown, which its rest shape (eqs 1-6) and its
    # cell's means are worked out from: a rest-shape edit makes the block again from them (``reshapes``)
    grown_length: np.ndarray | None = None
    grown_width: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        return sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray))

    @property
    def empty(self) -> bool:
        """No blade grows in the block (painted out): nothing to simulate or draw there."""
        return self.cell_density is not None and not bool(self.cell_density.any())


# Settings that change only the blades' rest shapes (eqs 1-6: the stiffness, its offset, the
# blades' weight; a species' ``stiffness`` column) and what follows from them (the cells'
# stiffness and rest tilt, the cards' height): every blade grows where and as it did.
REST_SHAPE = frozenset({"blade.root_stiffness", "blade.stiffness_offset", "blade.density"})
SPECIES_REST_SHAPE = frozenset({"stiffness"})


def reshapes(old: Params, new: Params) -> bool:
    """``new`` differs from ``old`` in rest-shape settings alone (``REST_SHAPE``), and in some:
    the blocks of ``new`` can be made from the blades ``old``'s blocks grew (``make_blocks``' ``before``)."""
    changed = edit_parts.changed_settings(old, new)

    def shape_only(name: str, a, b) -> bool:
        if name == "blade.species":
            columns = edit_parts.species_columns(a, b)
            return columns is not None and columns <= SPECIES_REST_SHAPE
        return name in REST_SHAPE

    return bool(changed) and all(shape_only(*setting) for setting in changed)


def _stiffness(params: Params, species: Species, kind: np.ndarray) -> np.ndarray:
    """Each blade's root stiffness: the field's times its species' (float64)."""
    return params.blade.root_stiffness * species.stiffness[kind]


def _painted(paint: Paint | None) -> Paint | None:
    """``paint``, or None where nothing is painted."""
    return None if paint is None or paint.empty else paint


class Species:
    """The species table as arrays (paper III.A (1))."""

    def __init__(self, params: Params):
        rows = params.species()
        weights = np.array([r["weight"] for r in rows], dtype=np.float64)
        self.p = weights / weights.sum()
        self.length = np.array([r["length"] for r in rows], dtype=np.float64)
        self.length_variation = np.array([r["length_variation"] for r in rows], dtype=np.float64)
        self.width = np.array([r["width"] for r in rows], dtype=np.float64)
        self.stiffness = np.array([r["stiffness"] for r in rows], dtype=np.float64)
        self.color = np.array([r["color"] for r in rows], dtype=np.float32).reshape(-1, 3)
        self.heads = np.array([r["heads"] for r in rows], dtype=np.float64)
        self.head_size = np.array([r["head_size"] for r in rows], dtype=np.float64)
        self.head_color = np.array([r["head_color"] for r in rows], dtype=np.float32).reshape(-1, 3)
        # a flower: the strip's cup or a mesh on its tip (heads.MESH_SHAPES, ``crowned``)
        self.crowned = heads.crowned(rows)
        self.flower = np.array([r["head_shape"] == "flower" for r in rows], dtype=bool) | self.crowned
        self.mean_length = float(np.dot(self.p, self.length))
        self.mean_variation = float(np.dot(self.p, self.length_variation))
        self.longest = float(np.max(self.length + 4.0 * self.length_variation))  # no blade is longer
        self.tallest_card = float(params.lod.card_height) * self.longest  # a tip is no higher than its length


def _sample_blades(rng: np.random.Generator, count: int, params: Params, species: Species, local=None):
    """Species, length (l = l_base + lambda*N(0,1), kept positive), width, stiffness, alpha of `count` blades.

    ``local``: (count, species) shares where species maps are painted (paint.py), or None. The
    species is the inverse CDF of one uniform number per blade: with the table's shares this is
    the draw ``Generator.choice`` makes (bit for bit), with local ones the same number picks from
    the shares where the blade stands. Blades where no species may grow get -1 (they do not grow)."""
    u = rng.random(count)
    if local is None:
        cdf = species.p.cumsum()
        cdf /= cdf[-1]
        kind = cdf.searchsorted(u, side="right").astype(np.int16)
    else:
        total = local.sum(axis=1)
        cdf = np.cumsum(local, axis=1) / np.where(total > 0.0, total, 1.0)[:, None]
        kind = np.minimum((u[:, None] >= cdf).sum(axis=1), len(species.p) - 1).astype(np.int16)
        kind[total <= 0.0] = -1
    barren = kind < 0
    kind = np.where(barren, 0, kind).astype(np.int16)
    base = species.length[kind]
    # paper III.A (1): delta_l = lambda * N(0,1); a blade keeps at least 15 % of the reference length,
    # and N(0,1) is held within +-4 so that the tallest blade is known from the parameters (culling)
    normal = np.clip(rng.standard_normal(count), -4.0, 4.0)
    length = np.maximum(base + species.length_variation[kind] * normal, 0.15 * base)
    width = species.width[kind] * np.clip(1.0 + 0.12 * rng.standard_normal(count), 0.6, 1.4)
    stiffness = _stiffness(params, species, kind)
    inclination = np.radians(params.blade.inclination) * rng.random(count)  # random initial alpha
    if local is not None:
        return kind, length, width, stiffness, inclination, barren
    return kind, length, width, stiffness, inclination


def _rest_tilt(params: Params, length, stiffness, inclination) -> np.ndarray:
    """Absolute rest tilt of each segment from eqs 1-6 (blade.py)."""
    n = params.blade.segments
    seg = length / n
    mu = blade.joint_stiffness(stiffness, seg, n, params.blade.stiffness_offset)  # eq 5
    theta = blade.rest_angles(inclination, seg, mu, params.blade.density)  # eqs 2-4, 6
    return blade.rest_tilt(inclination, theta)


def make_block(params: Params, grid: FieldGrid, species: Species, block: int,
               terrain: Heightfield | None = None, paint: Paint | None = None) -> Block:
    """Block ``block``'s blades and cells, from random streams keyed by (seed, purpose, block).

    ``paint`` (paint.py): which blades grow (``blade_alive``, ``cell_density``), their species and
    length where maps are painted. Its draws come after every draw of the plain field, so a field
    without paint is the same bits as before, and each blade's numbers never depend on the paint."""
    return make_blocks(params, grid, species, [block], terrain, paint)[0]


def make_blocks(params: Params, grid: FieldGrid, species: Species, blocks, terrain: Heightfield | None = None,
                paint: Paint | None = None, before: dict[int, Block] | None = None) -> list[Block]:
    """``make_block`` of each of ``blocks``, grown together (``_grow``: the meadow's noise over all
    their blades at once) and their blades' rest shapes worked out together
    (``blade.rest_angles_blocks``): the same bits as one by one, in less than half the time.
    ``before``: blocks made for settings that differ only in the rest shapes (``reshapes``), by id;
    a block found there keeps the blades it grew (nothing drawn again), its rest shapes worked out anew."""
    ids = [int(b) for b in blocks]
    kept = {b: before[b] for b in ids if before is not None and b in before}
    drawn = iter(_grow(params, grid, species, [b for b in ids if b not in kept], terrain, paint))
    grown = [_Grown.of(params, grid, species, b, kept[b], terrain, paint) if b in kept else next(drawn) for b in ids]
    n = int(params.blade.segments)
    if not grown or grown[0].length.size == 0:
        return [g.block(np.zeros((0, n))) for g in grown]
    length, stiffness, inclination = (np.stack([getattr(g, name) for g in grown])
                                      for name in ("length", "stiffness", "inclination"))
    seg = length / n
    mu = blade.joint_stiffness(stiffness, seg, n, params.blade.stiffness_offset)  # eq 5
    theta = blade.rest_angles_blocks(inclination, seg, mu, params.blade.density)  # eqs 2-4, 6
    return [g.block(blade.rest_tilt(g.inclination, angles)) for g, angles in zip(grown, theta)]


def _grow(params: Params, grid: FieldGrid, species: Species, blocks: list[int], terrain: Heightfield | None,
          paint: Paint | None) -> list[_Grown]:
    """Each block's blades as grown, the blocks' draws each from its own streams in the order one
    block alone draws them, and the meadow's noise (tussocks, patches, edge: pure functions of the
    place, point by point) worked out once over every block's blades (the same bits, fewer calls)."""
    grown = [_Grown(params, grid, species, b, terrain, paint) for b in blocks]
    if not grown:
        return grown
    f = params.field
    # paper III.A (2) and the tussocks (meadow.clumped): each blade pulled towards its clump's centre
    pulled = _split(meadow.clumped(np.concatenate([g.drawn for g in grown]), int(f.seed), float(f.clumping),
                                   float(f.clump_size)), grown)
    for g, xy in zip(grown, pulled):
        g.root_at(xy)
    shares = _local_shares(params, species, grown[0].painted, np.concatenate([g.root[:, :2] for g in grown]))
    for g, local in zip(grown, _split(shares, grown) if shares is not None else [None] * len(grown)):
        g.sample(local)
    lengths = _meadow_lengths(params, grid, np.concatenate([g.root[:, :2] for g in grown]),
                              np.concatenate([g.length for g in grown]))
    for g, length in zip(grown, _split(lengths, grown)):
        g.length = length
        g.meadow()
    return grown


def _split(values: np.ndarray, grown: list[_Grown]) -> list[np.ndarray]:
    """``values`` over every block's blades in turn, cut into each block's."""
    return np.split(values, np.cumsum([len(g.drawn) for g in grown])[:-1])


class _Grown:
    """A block's blades as grown (where, which species, how long, how stiff, how inclined), before
    their rest shapes: made in the steps ``_grow`` takes (``root_at``, ``sample``, ``meadow``),
    then ``block(rest_tilt)`` finishes it."""

    def __init__(self, params: Params, grid: FieldGrid, species: Species, block: int,
                 terrain: Heightfield | None, paint: Paint | None):
        self.params, self.grid, self.species, self.block_id, self.terrain = params, grid, species, int(block), terrain
        f = params.field
        cs, num, P = grid.cell_size, int(f.blades_per_cell), grid.cells_per_block ** 2
        self.centre64 = grid.cell_centers(self.block_id)
        self.rng = np.random.default_rng([int(f.seed), RNG_BLADES, self.block_id])
        # paper III.A (2): random position inside the cell and random orientation
        offset = self.rng.random((P * num, 2)) * cs - 0.5 * cs
        self.drawn = np.repeat(self.centre64, num, axis=0) + offset
        self.painted = _painted(paint)

    @classmethod
    def of(cls, params: Params, grid: FieldGrid, species: Species, block: int, made: Block,
           terrain: Heightfield | None, paint: Paint | None) -> _Grown:
        """Block ``block``'s blades as ``made`` (for settings that differ only in the rest shapes)
        grew them, their stiffness of ``params``: what ``_grow`` draws for it, bit for bit."""
        self = cls.__new__(cls)
        self.params, self.grid, self.species, self.block_id, self.terrain = params, grid, species, int(block), terrain
        self.centre64 = grid.cell_centers(self.block_id)
        self.painted = _painted(paint)
        self.root, self.facing, self.kind, self.shade = made.blade_root, made.blade_facing, made.blade_species, \
            made.blade_shade
        self.length, self.width = made.grown_length, made.grown_width
        self.stiffness = _stiffness(params, species, self.kind)  # (as _sample_blades draws it)
        self.inclination = made.blade_inclination  # (the rest shapes read it in float32)
        self.alive, self.head, self.flower, self.dry = made.blade_alive, made.blade_head, made.blade_flower, \
            made.blade_dry
        return self

    def root_at(self, pulled: np.ndarray) -> None:
        """Its roots where the tussocks pulled them (inside the field), on the terrain."""
        grid = self.grid
        root = self.root = np.empty((len(pulled), 3), dtype=np.float32)
        root[:, :2] = np.clip(pulled, grid.origin, np.asarray(grid.origin) + grid.size)
        root[:, 2] = ground_z(self.terrain, root[:, :2])  # rooted on the terrain surface
        self.facing = (self.rng.random(len(root)) * 2.0 * np.pi).astype(np.float32)

    def sample(self, local: np.ndarray | None) -> None:
        """Species, length, width, stiffness, inclination and shade, and which blades grow (paint),
        with the species' shares ``local`` where they stand (``_local_shares``)."""
        rng, root, painted = self.rng, self.root, self.painted
        n_blades = len(root)
        self.kind, length, self.width, self.stiffness, self.inclination, *barren = _sample_blades(
            rng, n_blades, self.params, self.species, local)
        self.shade = rng.random(n_blades).astype(np.float32)
        self.alive = None
        if painted is not None:
            grow_number = rng.random(n_blades)  # each blade's own: it grows where it is below the density
            scale = painted.length_at(root[:, :2])
            length = np.maximum(length * scale, MIN_BLADE_LENGTH)
            self.alive = (grow_number < painted.density_at(root[:, :2])) & (scale >= MIN_LENGTH_SCALE)
            if barren:
                self.alive &= ~barren[0]
        self.length = length

    def meadow(self) -> None:
        """Its heads, flowers and dry tips (after ``_meadow_lengths`` scaled its lengths)."""
        f = self.params.field
        self.head, self.flower, self.dry = meadow.heads_and_dryness(
            np.random.default_rng([int(f.seed), meadow.RNG_MEADOW, self.block_id]), self.kind, self.species,
            self.params)
        del self.rng, self.drawn

    def block(self, rest_tilt: np.ndarray) -> Block:
        """The block, with its blades' absolute rest tilts (n_blades, n) (eqs 1-6)."""
        params, grid, species, block, terrain = self.params, self.grid, self.species, self.block_id, self.terrain
        f = params.field
        cs, num, P, n = grid.cell_size, int(f.blades_per_cell), grid.cells_per_block ** 2, int(params.blade.segments)
        centre64, cell_center = self.centre64, self.centre64.astype(np.float32)
        length, width, stiffness, flower, alive = self.length, self.width, self.stiffness, self.flower, self.alive
        root, painted = self.root, self.painted
        # The cell's representative blade (paper V.B: blades of a cell share the cell's bend and twist):
        # the mean of its blades, or a sampled virtual blade when cells hold no blades.
        cell_rng = np.random.default_rng([int(f.seed), RNG_CELLS, block])
        cell_length, cell_width, cell_stiffness, cell_rest_tilt = _cell_blades(
            params, species, cell_rng, P, num, length, width, stiffness, rest_tilt)
        cell_facing = (cell_rng.random(P) * 2.0 * np.pi).astype(np.float32)
        # paper III.B: card height = reference height + stochastic modifier; random orientation. The
        # card stands for its cell's blades, so its height is that of the cell's tallest blade at rest
        # (the blades' own lengths are the stochastic part), times lod.card_height.
        shares = meadow.segment_shares(n, length, width, flower)  # a flower's head: its short top segments
        tallest = _tallest(P, num, length, rest_tilt, shares, alive, cell_length, cell_rest_tilt)
        cell_density = None
        if painted is not None and alive is not None:
            cell_density = alive.reshape(P, num).mean(axis=1).astype(np.float32) if num > 0 \
                else painted.density_at(centre64).astype(np.float32)
        card_height = params.lod.card_height * tallest
        card_facing = cell_rng.random(P) * np.pi
        card_shade = cell_rng.random(P)
        # the cards stand anywhere in their cell, like its blades: on the cell centres they would line
        # up in rows that a view along the grid sees through (radial streaks)
        card_center = centre64 + (cell_rng.random((P, 2)) - 0.5) * cs
        if terrain is None:
            z_range = np.zeros(2, np.float32)
        else:
            z_range = terrain.box_z_range(grid.block_bounds([block]))[0]
        f32 = np.float32
        return Block(
            blade_root=root, blade_facing=self.facing, blade_length=length.astype(f32), blade_width=width.astype(f32),
            blade_inclination=self.inclination.astype(f32), blade_shade=self.shade, blade_species=self.kind,
            blade_head=self.head, blade_flower=flower, blade_dry=self.dry,
            blade_rest_tilt=np.ascontiguousarray(rest_tilt, dtype=f32),
            blade_ground_slope=None if terrain is None else terrain.gradient(root[:, :2]),
            cell_center=cell_center, cell_ground=ground_z(terrain, cell_center).astype(f32),
            cell_length=cell_length, cell_width=cell_width, cell_root_stiffness=cell_stiffness.astype(f32),
            cell_rest_tilt=np.ascontiguousarray(cell_rest_tilt, dtype=f32), cell_facing=cell_facing,
            card_height=card_height.astype(f32), card_facing=card_facing.astype(f32),
            card_shade=card_shade.astype(f32), card_center=card_center.astype(f32),
            z_range=np.asarray(z_range, dtype=f32), blade_alive=alive, cell_density=cell_density,
            grown_length=np.asarray(length, dtype=np.float64), grown_width=np.asarray(width, dtype=np.float64))


def _meadow_lengths(params: Params, grid: FieldGrid, xy: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The blades' lengths at ``xy`` scaled by the meadow's patches and its thinning edge."""
    f = params.field
    if f.patchiness > 0.0:
        length = np.maximum(length * meadow.length_scale(xy, params), MIN_BLADE_LENGTH)
    if f.edge > 0.0:  # the field's edge thins out (meadow.edge_scale)
        length = np.maximum(length * meadow.edge_scale(xy, grid.origin, grid.size, params), MIN_BLADE_LENGTH)
    return length


def _local_shares(params: Params, species: Species, paint: Paint | None, xy: np.ndarray) -> np.ndarray | None:
    """(n, species) the species' shares where the blades stand: painted species maps times the
    meadow's patches (meadow.py); None where the table's shares hold everywhere."""
    local = None if paint is None else paint.species_weights_at(xy, species.p)
    patched = meadow.species_weights(xy, params, species.p if local is None else np.ones(len(species.p)))
    if patched is None:
        return local
    return patched if local is None else local * patched


def _cell_blades(params: Params, species, cell_rng, P: int, num: int, length, width, stiffness, rest_tilt) -> tuple:
    """(length, width, root stiffness, rest tilt) of each cell's representative blade (paper V.B:
    blades of a cell share the cell's bend and twist): the mean of its blades, or a virtual blade
    drawn from ``cell_rng`` when cells hold no blades."""
    if num > 0:
        def per_cell(values: np.ndarray) -> np.ndarray:
            return values.reshape((P, num) + values.shape[1:]).mean(axis=1).astype(np.float32)

        return per_cell(length), per_cell(width), per_cell(stiffness), per_cell(rest_tilt)
    _, c_len, c_wid, c_stiff, c_inc = _sample_blades(cell_rng, P, params, species)
    return (c_len.astype(np.float32), c_wid.astype(np.float32), c_stiff.astype(np.float32),
            _rest_tilt(params, c_len, c_stiff, c_inc).astype(np.float32))


def _tallest(P: int, num: int, length, rest_tilt, shares, alive, cell_length, cell_rest_tilt) -> np.ndarray:
    """(P,) each cell's tallest blade at rest, of the blades that grow where some do (a card
    stands for them), the representative blade's height when cells hold no blades."""
    if num == 0:
        return blade.tip_height(cell_length, cell_rest_tilt)
    tips = blade.tip_height(length, rest_tilt, shares).reshape(P, num)
    if alive is not None:  # the card stands for the blades that grow
        grown = alive.reshape(P, num)
        tips = np.where(grown.any(axis=1)[:, None], np.where(grown, tips, 0.0), tips)
    return tips.max(axis=1)


class BlockCache:
    """Blocks by id, generated on first use and kept within ``budget`` bytes (least recently
    used first out). ``get`` never drops a block it is returning."""

    def __init__(self, params: Params, terrain: Heightfield | None = None, budget: int = DEFAULT_CACHE_BYTES,
                 paint: Paint | None = None, before: BlockCache | None = None):
        """``before``: the cache of a field whose settings differ from ``params`` only in the rest
        shapes (``reshapes``; the same terrain and paint), its blocks as they are now: each block it
        holds is made from the blades it grew (its rest shapes anew), not drawn again."""
        self.params = params
        # (each taken once, when its block is made)
        self._before = dict(before._blocks) if before is not None and reshapes(before.params, params) else None
        self.grid = FieldGrid.of(params)
        self.species = Species(params)
        self.terrain = terrain
        self.paint = _painted(paint)
        self.budget = int(budget)
        self._blocks: OrderedDict[int, Block] = OrderedDict()
        self.nbytes = 0
        self.made = 0  # blocks generated so far (a measure of work)

    def __len__(self) -> int:
        return len(self._blocks)

    def fork(self) -> BlockCache:
        """A cache of its own holding the blocks this one holds now (shared: a block never changes
        once made), for a field's ``twin`` on another thread."""
        other = copy.copy(self)
        other._blocks = OrderedDict(self._blocks)
        return other

    def adopt(self, other: BlockCache) -> None:
        """Keep the blocks ``other`` holds that this cache lacks, within the budget: ``other`` is a
        ``fork`` of this one (the same settings of the blocks), whose field made them first (a new
        field's first look, ``bridge/builds.py``)."""
        for block_id, block in other._blocks.items():
            if block_id not in self._blocks and self.nbytes + block.nbytes <= self.budget:
                self._blocks[block_id] = block
                self.nbytes += block.nbytes

    def block_bytes(self) -> int:
        """Bytes one block takes (every block has the same shapes)."""
        f, n = self.params.field, int(self.params.blade.segments)
        P = self.grid.cells_per_block ** 2
        B = P * int(f.blades_per_cell)
        per_blade = 4 * (3 + 8 + n + (2 if self.terrain is not None else 0)) + 2 + 16  # (16: grown_length, _width)
        per_cell = 4 * (2 + 1 + 3 + n + 1 + 3)
        return B * per_blade + P * per_cell + 8

    def capacity(self) -> int:
        """How many blocks the budget holds."""
        return max(1, self.budget // max(1, self.block_bytes()))

    def drop(self, region) -> int:
        """Forget the blocks whose ground rectangle meets the box ``region`` (x0, y0, x1, y1; the
        paint there changed): they are made again when asked for. Returns how many were dropped."""
        x0, y0, x1, y1 = region
        ids = np.fromiter(self._blocks, np.int64, len(self._blocks))
        if ids.size == 0:
            return 0
        b = self.grid.block_bounds(ids)
        gone = ids[(b[:, 2] >= x0) & (b[:, 0] <= x1) & (b[:, 3] >= y0) & (b[:, 1] <= y1)]
        for block in gone.tolist():
            self.nbytes -= self._blocks.pop(block).nbytes
        return int(gone.size)

    def get(self, blocks) -> list[Block]:
        ids = [int(b) for b in np.asarray(blocks, dtype=np.int64).ravel()]
        if len(ids) > self.capacity():
            raise ParameterError(
                "simulation.cache_mb",
                f"the camera sees {len(ids):,} blocks but the block cache holds {self.capacity():,} "
                f"({self.budget / 2**20:.0f} MB); raise simulation.cache_mb or shorten lod.card_far")
        missing = [b for b in dict.fromkeys(ids) if b not in self._blocks]
        made: dict[int, Block] = {}
        for at in range(0, len(missing), MADE_TOGETHER):
            group = missing[at:at + MADE_TOGETHER]
            before = None if self._before is None else {b: self._before.pop(b) for b in group if b in self._before}
            made.update(zip(group, make_blocks(self.params, self.grid, self.species, group, self.terrain, self.paint,
                                               before)))
        out = []
        for b in ids:
            block = self._blocks.get(b)
            if block is None:
                block = made[b]
                self._blocks[b] = block
                self.nbytes += block.nbytes
                self.made += 1
            else:
                self._blocks.move_to_end(b)
            out.append(block)
        keep = set(ids)
        while self.nbytes > self.budget and len(self._blocks) > len(keep):
            old, block = next(iter(self._blocks.items()))
            if old in keep:
                self._blocks.move_to_end(old)
                continue
            del self._blocks[old]
            self.nbytes -= block.nbytes
        return out

