"""The cards' texture (paper III.B): an atlas of the field's own blades, and where a card maps into it.

The paper covers each card with a "semi-transparency grass pack texture". Windgrass ships no
image: ``card_atlas`` draws the blades of sample cells of the field (their shapes, coverage and
colours, ``sward.sample_blades``) into ``CARD_VARIANTS`` square variants side by side, and each
cell's card shows one of them (``card_variants``, ``card_uvs``). The bridge packs the atlas into a
Blender image (``bridge/textures.py``). Numpy only.
"""

from __future__ import annotations

import numpy as np

from . import edit_parts, meadow, plants
from .blocks import Species
from .schema import Params
from .sward import colour_ramp, sample_blades, shade_value

# Purpose of the random stream that picks each cell's variant (np.random.default_rng([purpose, P])).
RNG_CARD_VARIANTS = 8

CARD_VARIANTS = 8  # variants of the atlas; each cell of a block shows one (card_variants)
CARD_PIXELS = 256  # height of the atlas; each variant is a square of this many pixels
ATLAS_BANDS = 8  # atlas_cells matches the field's paint in this many bands of a card's height
BAND_COUNTS = 0.3  # ... and its counts (species, heads) with this weight against each band's
FLOWER_AREA = 0.5  # ... and each species' flowers' area with this weight
OVERLAP_MAX = 1.2  # ... among cells whose blades overlap on the card no more (``_typical``)
OVERLAP_TRIES = 32  # ... tried in order of their miss
OVERLAP_PIXELS = 64  # ... drawn this large to tell


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK, edit_parts.LOD))
def card_atlas(params: Params, variants: int = CARD_VARIANTS, size: int = CARD_PIXELS,
               own: plants.Plants | None = None) -> np.ndarray:
    """RGBA atlas of the cards (paper III.B), (size, variants * size, 4) float32, straight alpha,
    row 0 at the bottom (Blender's pixel order): variant k is the view along a card's normal of
    the blades of the k-th cell ``atlas_cells`` picks from the sample (``sward.sample_blades``),
    at their rest shape, in their own colours.

    A card is ``lod.card_width`` cells wide and stands for its cell's blades, so the atlas holds
    exactly those: their colour ramp (the blade material's, with each blade's shade), shape and
    coverage are the blades'. Each blade keeps its full width and its whole droop (to the side its
    lean points to): seen from a direction v, a blade shows w |sin(v - facing)| of its width (and
    |cos| of its droop) and the card |cos(v - card normal)| of its area; averaged over the
    directions all are 2/pi, so the card's coverage must be the blades' whole area over the card's
    (``card_coverage``). Sizes projected onto the card would count that foreshortening twice (the
    cards 1.57 times too sparse). A card is periodic across (``_draw_strip``): what a long droop
    or a root pulled into a tussock carries past one edge comes in at the other, and the
    variant's strips are widened only to make up where blades overlap (1.04-1.42 times in the
    default scene; widened 4 times for droops they were straw-coloured verticals). The variant's
    height spans its card's height (``card_height``). A species drawn as the artist's own plant
    (``own``, ``plants.py``) shows that plant on its stems, as Blender bends it along them."""
    block = sample_blades(params)
    if block.blade_root.shape[0] == 0:  # (no blades: field.density 0, cards of nothing, bare ground)
        return np.zeros((size, variants * size, 4), np.float32)
    image = np.empty((size, variants * size, 4), np.float32)
    for k, cell in enumerate(atlas_cells(params, variants)):
        rgb, alpha = draw_card(params, block, int(cell), size, own)
        image[:, k * size:(k + 1) * size, :3] = rgb
        image[:, k * size:(k + 1) * size, 3] = alpha
    return image


def draw_card(params: Params, block, cell: int, size: int = CARD_PIXELS,
              own: plants.Plants | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(rgb (size, size, 3), alpha (size, size)) the card of ``block``'s cell ``cell`` as the atlas
    draws it: its blades, their strips widened until the card covers their whole area (the own
    plants, ``own``, drawn as they are)."""
    num = int(params.field.blades_per_cell)
    blades = list(range(cell * num, (cell + 1) * num))
    drawn = [b for b in blades if own is None or own.of_species(int(block.blade_species[b])) is None]
    target = _blade_share(params, block, cell, drawn) if drawn else 0.0
    if len(drawn) < len(blades):  # (the plants cover what they cover: their own area, not widened)
        target += float(_draw_variant(params, block, cell, blades, size, 1.0, own, strips=False)[1].mean())
    widen = 1.0
    for _ in range(3):  # coverage is about linear in the width: converges in a step or two
        rgb, alpha = _draw_variant(params, block, cell, blades, size, widen, own)
        covered = float(alpha.mean())
        if covered <= 0.0 or abs(covered - target) <= 0.02 * target:
            break
        widen = min(4.0, widen * target / covered)
    return rgb, alpha


def atlas_cells(params: Params, variants: int = CARD_VARIANTS) -> np.ndarray:
    """(variants,) the cells of the sample (``sward.sample_blades``) whose blades the atlas draws:
    chosen one by one so that together they hold the field's mix, each species, its flowers and
    its seed heads as many times as the whole sample holds them per cell (times the cells drawn so
    far), and its paint at every height of a card (``band_paint``). A card shows a few blades, and
    the atlas a few dozen: the first cells of the sample held one flower of one species in 24
    blades where the field has 9 % flowers of two, so the cards' band lost the field's flowers
    (issue #34). Each flower the atlas should hold half a time or more is there: the first cells
    drawn hold one of each such species' (the nearest count alone gave Add Grass Field's cards two
    daisies and no buttercup, where its 16 blades should hold 1.7 and 0.65). Ties go to the
    earlier cell, so the choice is a pure function of the sample."""
    block = sample_blades(params)
    num = int(params.field.blades_per_cell)
    cells = block.cell_center.shape[0]
    kind = np.eye(int(block.blade_species.max()) + 1)[block.blade_species]  # (blades, species) one-hot
    headed = ((block.blade_head > 0.0) | (block.blade_flower > 0.0))[:, None]

    def per_cell(values: np.ndarray) -> np.ndarray:
        return values.reshape(cells, num, -1).sum(axis=1)

    # per blade: its species, its species' head or flower (weighed as what the eye finds first in
    # a meadow). (Not its length: the cells nearest the mean length of the paper's even field
    # made its cards 1.3 times as bright as its blades from 1.1 m, and a field of one species
    # without heads now keeps the sample's first cells.)
    counts = per_cell(np.concatenate([kind, 2.0 * headed * kind], axis=1))
    # and each band of its card's height, as a grazing ray crosses it: chosen by the counts alone,
    # the atlas's bands held 0.4-2 times the field's paint (the top ones most: which stems carry
    # the few flowers), and the card band's rows came out 0.85-1.35 times the blades' from 1.1 m
    # from one seed of the default scene to the next
    paint, area, heads = band_paint(params, block)
    # and the area of each species' flowers, which the eye finds first in a meadow and the paint
    # hardly weighs (FLOWER_AREA): matched by their count alone, the default meadow's card band
    # showed buttercup yellow in 1.5 % of its pixels from 1.1 m where its blades show 7 % (4-5 %)
    drawn = np.concatenate([paint.reshape(cells, -1), area, heads], axis=1)  # shares of each card
    # A variant stands on cells of every height, so the field's cards show the mean share times
    # the mean height, where the field's cells hold their own share times their own height: the
    # target is that height-weighted mean (in the default meadow within 4 % of the plain mean).
    tall = block.card_height.astype(np.float64) / max(float(block.card_height.mean()), 1e-12)
    field = (drawn * tall[:, None]).mean(axis=0)
    norm = 1.0 / np.maximum(field, 1e-12)
    norm[-heads.shape[1]:] *= FLOWER_AREA
    features = np.concatenate([BAND_COUNTS * counts, drawn * norm], axis=1)
    target = np.concatenate([BAND_COUNTS * counts.mean(axis=0), field * norm])
    flowers = per_cell(kind * (block.blade_flower > 0.0)[:, None])  # (cells, species) flowers of each
    expected = flowers.mean(axis=0) * variants
    first = [int(k) for k in np.argsort(-expected, kind="stable") if expected[k] >= 0.5]
    chosen: list[int] = []
    total = np.zeros_like(target)
    for k in range(variants):
        miss = ((total[None, :] + features - (k + 1) * target[None, :]) ** 2).sum(axis=1)
        if chosen:
            miss[chosen] = np.inf  # (a cell once: more variants than cells repeat below)
        if k < len(first):
            flowered = np.where(flowers[:, first[k]] > 0.0, miss, np.inf)  # a cell with that species' flower
            miss = flowered if np.isfinite(flowered).any() else miss
        cell = _typical(params, block, miss) if len(chosen) < cells else chosen[k % cells]
        chosen.append(cell)
        total += features[cell]
    return np.array(chosen, dtype=np.int64)


def _typical(params: Params, block, miss: np.ndarray) -> int:
    """The cell of least ``miss`` whose blades overlap one another on its card no more than
    OVERLAP_MAX times (their area over what they cover, drawn unwidened): a card stops what its
    blades stop from any side, and a cell whose strips lie over one another (a tussock's, a
    flower's head over a neighbour) stops from every side as little as on its card, where the
    atlas widens them to their whole area (up to 1.6 times what they stop; the field's cells
    1.06 on average). The least ``miss`` when every candidate overlaps more."""
    num = int(params.field.blades_per_cell)
    order = np.argsort(miss, kind="stable")
    for cell in order[:OVERLAP_TRIES]:
        if not np.isfinite(miss[cell]):
            break
        blades = list(range(int(cell) * num, (int(cell) + 1) * num))
        _, alpha = _draw_variant(params, block, int(cell), blades, OVERLAP_PIXELS, 1.0)
        covered = float(alpha.mean())
        if covered > 0.0 and _blade_share(params, block, int(cell), blades) <= OVERLAP_MAX * covered:
            return int(cell)
    return int(order[0])


def _strip_parts(params: Params, block, blades: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((b, n + 1), (b, n, 2, 3), (b, n)) of ``block``'s blades ``blades``: each joint's width (m),
    each segment's colour at its bottom and top (the blade material's ramp with each blade's shade;
    heads, flowers and dry tips included) and each segment's length (m), as the atlas draws them."""
    n = int(params.blade.segments)
    species = Species(params)
    head, flower, kind = block.blade_head[blades], block.blade_flower[blades], block.blade_species[blades]
    widths = meadow.joint_widths(params.blade.tip_width, n, head, flower) * \
        block.blade_width[blades].astype(np.float64)[:, None]
    joints = meadow.joint_colours(n, species.color[kind], species.head_color[kind], block.blade_dry[blades],
                                  head, flower)  # (b, n + 1, 3), heads and dry tips
    ends = meadow.segment_colours(joints, flower).astype(np.float64)  # (b, n, bottom/top, 3): a flower's head wholly
    v_ends = (np.arange(n)[:, None] + np.array([0.0, 1.0])[None, :]) / n  # the material's v there
    shade = shade_value(block.blade_shade[blades])
    colours = colour_ramp(ends, np.broadcast_to(v_ends, ends.shape[:-1])) * shade[:, None, None, None]
    segs = block.blade_length[blades].astype(np.float64)[:, None] * meadow.segment_shares(
        n, block.blade_length[blades], block.blade_width[blades], flower)
    return widths, colours, segs


def band_paint(params: Params, block, bands: int = ATLAS_BANDS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((cells, bands, 3), (cells, bands), (cells, species)) for each cell of ``block``: its
    blades' paint (linear RGB times area) and area in each of ``bands`` equal bands of its card's
    height, and the area of each species' flowers (their heads), over the card's area, as
    ``_draw_variant`` draws them at rest (each row of a segment as wide as the strip there, in its
    colour between the joints; the middle of the band's part of a segment stands for it) before
    they overlap."""
    n, num = int(params.blade.segments), int(params.field.blades_per_cell)
    cells = block.cell_center.shape[0]
    species = Species(params)
    if num == 0 or cells == 0:
        return np.zeros((cells, bands, 3)), np.zeros((cells, bands)), np.zeros((cells, len(species.p)))
    kind = block.blade_species
    widths, colour, seg = _strip_parts(params, block, np.arange(len(kind)))
    widths = widths / _card_width(params)  # (B, n + 1) in card widths
    rise = np.cumsum(seg * np.cos(block.blade_rest_tilt.astype(np.float64)), axis=1)
    height = np.repeat(np.maximum(block.card_height.astype(np.float64), 1e-9), num)
    v = np.concatenate([np.zeros((len(seg), 1)), rise], axis=1) / height[:, None]  # joints' v on the card
    v0, v1 = v[:, :-1, None], v[:, 1:, None]
    edges = np.linspace(0.0, 1.0, bands + 1)
    low = np.maximum(np.minimum(v0, v1), edges[:-1])  # (B, n, bands): the band's part of each segment
    high = np.minimum(np.maximum(v0, v1), edges[1:])
    dv = np.clip(high - low, 0.0, None)
    t = np.clip((0.5 * (low + high) - v0) / np.where(v1 == v0, 1e-9, v1 - v0), 0.0, 1.0)
    area = (widths[:, :-1, None] + (widths[:, 1:] - widths[:, :-1])[..., None] * t) * dv
    tint = colour[:, :, None, 0] + (colour[:, :, None, 1] - colour[:, :, None, 0]) * t[..., None]
    paint = (area[..., None] * tint).sum(axis=1).reshape(cells, num, bands, 3).sum(axis=1)
    opened = (block.blade_flower > 0.0)[:, None] & (np.arange(n) >= n - meadow.flower_segments(n))[None, :]
    heads = (area.sum(axis=2) * opened).sum(axis=1)[:, None] * np.eye(len(species.p))[kind]  # (B, species)
    return (paint, area.sum(axis=1).reshape(cells, num, bands).sum(axis=1),
            heads.reshape(cells, num, -1).sum(axis=1))


def _card_width(params: Params) -> float:
    """A card's width (m): lod.card_width cells."""
    return float(params.lod.card_width) * float(params.field.cell_size)


def _blade_share(params: Params, block, cell: int, blades) -> float:
    """Whole area of the cell's blades (tapered strips with their heads, face on) over its card's area."""
    widths, _, segs = _strip_parts(params, block, np.asarray(list(blades), dtype=np.int64))
    area = (0.5 * (widths[:, :-1] + widths[:, 1:]) * segs).sum()  # the strips' mean widths (with heads)
    return float(area) / (_card_width(params) * float(block.card_height[cell]))


def _draw_variant(params: Params, block, cell: int, blades, size: int, widen: float,
                  own: plants.Plants | None = None, strips: bool = True):
    """(rgb (size, size, 3), alpha (size, size)) of one card: its blades drawn over one another
    (a species of ``own``: its plant; ``strips`` False: the plants alone)."""
    card_w = _card_width(params)
    rgb = np.zeros((size, size, 3), np.float64)
    alpha = np.zeros((size, size), np.float64)
    ys = (np.arange(size) + 0.5) / size
    height = float(block.card_height[cell])
    axis = float(block.card_facing[cell])
    a = np.array([np.cos(axis), np.sin(axis)])
    blades = np.asarray(blades, dtype=np.int64)  # (their parts alone: a block holds thousands)
    widths, colours, segs = _strip_parts(params, block, blades)
    head, flower = block.blade_head[blades], block.blade_flower[blades]
    drawn = []
    for i, b in enumerate(blades):
        facing = float(block.blade_facing[b])
        lean = 1.0 if float(np.array([np.cos(facing), np.sin(facing)]) @ a) >= 0.0 else -1.0
        seg = segs[i]
        tilt = block.blade_rest_tilt[b].astype(np.float64)
        along = np.concatenate([[0.0], np.cumsum(seg * np.sin(tilt))]) * lean
        up = np.concatenate([[0.0], np.cumsum(seg * np.cos(tilt))])
        root = float((block.blade_root[b, :2] - block.card_center[cell]) @ a)
        drawn.append((i, (root + along) / card_w + 0.5, up))  # u: 0 .. 1 across the card
    # The card is periodic across (``_draw_strip``), so where its blades stand along it is free:
    # its largest head or flower is put in the middle, not split over the two edges.
    heads = [float(max(head[i], flower[i])) for i, _, _ in drawn]
    shift = 0.5 - drawn[int(np.argmax(heads))][1][-1] if heads and max(heads) > 0.0 else 0.0
    for i, u, up in drawn:
        b = int(blades[i])
        shape = own.of_species(int(block.blade_species[b])) if own is not None else None
        if shape is None:
            if strips:
                _draw_strip(rgb, alpha, ys, u + shift, up / height, 0.5 * widen * widths[i] / card_w, colours[i])
            continue
        facing = float(block.blade_facing[b])
        side, normal = np.array([-np.sin(facing), np.cos(facing)]), -np.array([np.cos(facing), np.sin(facing)])
        arc = np.concatenate([[0.0], np.cumsum(segs[i])])  # (rigid segments: the stem's own arc shares)
        plants.draw(rgb, alpha, shape, float(u[0]) + shift, (float(side @ a), float(normal @ a)), u - u[0],
                    up / height, float(segs[i].sum()) / card_w, arc / max(float(arc[-1]), 1e-12))
    covered = alpha > 1e-6
    rgb[covered] /= alpha[covered][:, None]
    # Where no blade covers the card, the colour is the card's coverage-weighted mean colour of
    # that row (or of the whole card): a renderer that stops at a card after many transparent
    # layers (``materials.card_material``) shows grass there, not black.
    total = alpha.sum()
    fallback = (rgb * alpha[..., None]).sum(axis=(0, 1)) / total if total > 0 else np.zeros(3)
    row_w = alpha.sum(axis=1)
    row_mean = (rgb * alpha[..., None]).sum(axis=1) / np.maximum(row_w, 1e-9)[:, None]
    row = np.where(row_w[:, None] > 1e-3, row_mean, fallback)
    empty = ~covered
    rgb[empty] = np.broadcast_to(row[:, None, :], rgb.shape)[empty]
    return np.clip(rgb, 0.0, 1.0), alpha


def _draw_strip(rgb, alpha, ys, u, v, half, colour) -> None:
    """Composite one blade (a tapered strip through points (u, v) with half-widths ``half``, in
    card units, coloured ``colour`` (n, bottom/top, 3) along each segment) over a square card
    image, one row at a time: each row crosses the strip where its height v lies between two
    joints; edges anti-aliased over one pixel."""
    size = alpha.shape[1]
    rows = np.flatnonzero((ys >= v.min()) & (ys <= v.max()))
    if rows.size == 0:
        return
    y = ys[rows]
    j = np.clip(np.searchsorted(v, y) - 1, 0, len(v) - 2)
    dv = np.maximum(v[j + 1] - v[j], 1e-9)
    t = np.clip((y - v[j]) / dv, 0.0, 1.0)
    centre = u[j] + (u[j + 1] - u[j]) * t
    width = half[j] + (half[j + 1] - half[j]) * t
    col = colour[j, 0] + (colour[j, 1] - colour[j, 0]) * t[:, None]
    xs = (np.arange(size) + 0.5) / size
    # across the card periodically: what leaves one edge comes in at the other (cards overlap their
    # neighbours), so a long droop or a root pulled into a tussock keeps its area, not widened
    off = np.abs((xs[None, :] - centre[:, None] + 0.5) % 1.0 - 0.5)
    cover = np.clip((width[:, None] - off) * size + 0.5, 0.0, 1.0)
    rgb[rows] = col[:, None, :] * cover[..., None] + rgb[rows] * (1.0 - cover[..., None])
    alpha[rows] = cover + alpha[rows] * (1.0 - cover)


def card_coverage(params: Params) -> tuple[float, float]:
    """(mean alpha of the atlas, the blades' whole area / card area of the same cells): a check
    that the cards cover what their blades cover."""
    atlas = card_atlas(params)
    block = sample_blades(params)
    num = int(params.field.blades_per_cell)
    area = cards = 0.0
    for cell in atlas_cells(params):
        card_area = _card_width(params) * float(block.card_height[cell])
        cards += card_area
        area += _blade_share(params, block, cell, range(cell * num, (cell + 1) * num)) * card_area
    return float(atlas[..., 3].mean()), area / cards


def card_uvs(grid) -> np.ndarray:
    """(cells_per_block**2 * 4, 2) float32 per face corner: v = 0 ground .. 1 top; u spans one
    variant of the atlas (``card_atlas``), ``card_variants(grid)[p]`` for the
    block's cell p."""
    one = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
    variant = card_variants(grid)
    uv = np.tile(one, (grid.cells_per_block_total, 1)).reshape(-1, 4, 2)
    uv[..., 0] = (uv[..., 0] + variant[:, None]) / CARD_VARIANTS
    return np.ascontiguousarray(uv.reshape(-1, 2), dtype=np.float32)


def card_variants(grid) -> np.ndarray:
    """(cells_per_block**2,) the atlas variant of each cell of a block: drawn at random (a fixed
    stream), so no row or column of cards repeats a pattern along the grid (streaks)."""
    P = grid.cells_per_block_total
    return np.random.default_rng([RNG_CARD_VARIANTS, P]).integers(0, CARD_VARIANTS, P)


# What a card's UVs depend on besides the block's size: the slot objects are rebuilt when it changes.
UV_LAYOUT = f"card atlas {CARD_VARIANTS} variants, stream {RNG_CARD_VARIANTS}"
