"""Far grass as the grass itself looks from afar (paper III.C): the sward's height and colour.

The far level of detail (eq 10: the ground texture) stands for the blades it replaces, so its
look is computed from them: a sample block of the field's own blades (``blocks.make_block``,
species, lengths, rest shapes) and the blade material's colour ramp (a dark base to the species'
tip colour over the lower 70 % of the blade, ``bridge/materials.py``):

* ``canopy_height``: where a low, grazing view stops seeing through the sward: the height below
  which the blades hide the ground, taken as the mean of the blades' rest tip heights times
  CANOPY_SHARE. The far texture lies on a plane at that height, so at the horizon the field's
  silhouette is the grass's, not the ground's.
* ``sward_depth``: how much blade a ray crosses that leaves the field at height z, which makes the
  field's edge against the sky as ragged and see-through as its blades (a fringe rising from the
  canopy plane to the tallest tip, ``sward_top``), in the colour of the blades' parts that stand
  above the canopy plane (``fringe_colour``: tips, lit like the blades, not shaded by others).
* ``sward_colour``: the colour of the blades as a grazing view sees them: the mean colour of the
  upper part of each blade (the part not hidden by the sward), weighted by its width (strips
  taper to ``blade.tip_width``) and by species share.

Numpy only (no Blender); the bridge writes the values into the materials.
"""

from __future__ import annotations

import numpy as np

from . import blade
from .blocks import Species, make_block
from .grid import FieldGrid
from .schema import Params

BLADE_BASE_COLOUR = (0.018, 0.03, 0.008)  # the blade material's root colour (linear RGB)
GRADIENT_END = 0.7  # the blade material darkens the lower 70 % of the blade towards the root
CANOPY_SHARE = 0.75  # a grazing view sees the sward down to three quarters of the tips' mean height
PROFILE_POINTS = 33  # heights from the ground to the tallest tip at which ``sward_profile`` gives the depth
VISIBLE_FROM = 0.35  # of a blade's length: the part below is hidden by the sward from afar


def sample_blades(params: Params):
    """A block of the field's own blades (block 0: every block is drawn from the same law)."""
    return make_block(params, FieldGrid.of(params), Species(params), 0)


def tip_heights(params: Params) -> np.ndarray:
    """Rest height of each sample blade's tip (m): sum of l/n cos(tilt) over its segments."""
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return blade.tip_height(block.cell_length, block.cell_rest_tilt)
    return blade.tip_height(block.blade_length, block.blade_rest_tilt)


def canopy_height(params: Params) -> float:
    """Height (m) of the plane that the far texture lies on."""
    return _canopy(tip_heights(params))


def sward_top(params: Params) -> float:
    """Height (m) of the tallest rest tip: the top of the fringe along the field's edge."""
    return float(max(1e-3, tip_heights(params).max()))


def sward_depth(params: Params, heights: np.ndarray) -> np.ndarray:
    """Silhouette depth tau(z) of the sward above each height z (m): the area of blade above z per
    square metre of ground, as a horizontal ray sees it. A segment of a strip leaning by theta
    from the vertical shows a horizontal ray |cos theta cos(facing - ray)| of its face, 2/pi cos
    theta on average over the directions: its width times its rise, times 2/pi.

    A ray that descends with slope s (rise over run) and leaves the field at height z was at
    height z + s d a distance d before, so it crossed (1/s) * integral of the blade area per
    height above z: tau(z) / s of blade, and is stopped with probability 1 - exp(-tau(z) / s)."""
    z = np.asarray(heights, np.float64)
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return np.zeros_like(z)
    low, high, seen = _segment_spans(params, block)
    above = np.clip((high[None] - z[:, None, None]) / np.maximum(high - low, 1e-9)[None], 0.0, 1.0)
    ground = block.cell_center.shape[0] * float(params.field.cell_size) ** 2  # the block's area
    return (above * seen[None]).sum(axis=(1, 2)) * (2.0 / np.pi) / ground


def _segment_spans(params: Params, block):
    """(lowest, highest point, width times rise) of every segment of ``block``'s blades at rest,
    each (blades, segments): what a horizontal ray sees of a segment lies between the two."""
    n = int(params.blade.segments)
    seg = block.blade_length.astype(np.float64)[:, None] / n
    rise = seg * np.cos(block.blade_rest_tilt.astype(np.float64))
    joint = np.concatenate([np.zeros((rise.shape[0], 1)), np.cumsum(rise, axis=1)], axis=1)
    taper = 1.0 - (1.0 - params.blade.tip_width) * (np.arange(n) + 0.5) / n
    seen = block.blade_width.astype(np.float64)[:, None] * taper[None, :] * np.abs(rise)
    return np.minimum(joint[:, :-1], joint[:, 1:]), np.maximum(joint[:, :-1], joint[:, 1:]), seen


def fringe_colour(params: Params) -> tuple[float, float, float]:
    """Mean linear RGB of the blades' parts above the canopy plane, weighted by the area that a
    horizontal ray sees (width times rise), in the blade material's colours with each blade's
    shade (as the card atlas draws them)."""
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return sward_colour(params)
    n = int(params.blade.segments)
    low, high, seen = _segment_spans(params, block)
    above = np.clip((high - canopy_height(params)) / np.maximum(high - low, 1e-9), 0.0, 1.0)
    weight = seen * above
    if weight.sum() <= 0.0:
        return sward_colour(params)
    tip = Species(params).color.astype(np.float64)[block.blade_species.astype(np.int64)]
    # the upper part of each segment (above the plane) at its middle height along the blade
    v = (np.arange(n) + 1.0 - 0.5 * above) / n
    colour = blade_colour_ramp(tip, v) * (0.7 + 0.6 * block.blade_shade.astype(np.float64))[:, None, None]
    return tuple(float(c) for c in (colour * weight[..., None]).sum(axis=(0, 1)) / weight.sum())


def sward_profile(params: Params, points: int = PROFILE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(heights from the ground to ``sward_top``, ``sward_depth`` at each): what the canopy
    material interpolates (``materials.canopy_material``)."""
    heights = np.linspace(0.0, sward_top(params), points)
    return heights, sward_depth(params, heights)


def _canopy(tips: np.ndarray) -> float:
    return float(CANOPY_SHARE * np.mean(tips))


def _card_width(params: Params) -> float:
    """A card's width (m): lod.card_width cells."""
    return float(params.lod.card_width) * float(params.field.cell_size)


def blade_colour_ramp(tip: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The blade material's colour at heights ``v`` (0 root .. 1 tip) for tip colours ``tip``
    (..., 3): a smoothstep from the base colour to the tip colour over v in [0, GRADIENT_END]."""
    u = np.clip(v / GRADIENT_END, 0.0, 1.0)
    s = u * u * (3.0 - 2.0 * u)
    base = np.asarray(BLADE_BASE_COLOUR)
    return base + (np.asarray(tip)[..., None, :] - base) * s[..., None]


def sward_colour(params: Params) -> tuple[float, float, float]:
    """Mean linear RGB of the visible upper part of the field's blades (see module doc)."""
    species = Species(params)
    v = np.linspace(VISIBLE_FROM, 1.0, 64)
    width = 1.0 - (1.0 - params.blade.tip_width) * v  # the strip's taper
    ramp = blade_colour_ramp(species.color.astype(np.float64), v)  # (species, 64, 3)
    per_species = (ramp * width[None, :, None]).sum(axis=1) / width.sum()
    return tuple(float(c) for c in species.p @ per_species)


CARD_VARIANTS = 8  # variants of the atlas; each cell of a block shows one (kinematics.card_variants)
CARD_PIXELS = 256  # height of the atlas; each variant is a square of this many pixels


def card_atlas(params: Params, variants: int = CARD_VARIANTS, size: int = CARD_PIXELS) -> np.ndarray:
    """RGBA atlas of the cards (paper III.B), (size, variants * size, 4) float32, straight alpha,
    row 0 at the bottom (Blender's pixel order): variant k is the view along a card's normal of
    the blades of cell k of the sample block, at their rest shape, in their own colours.

    A card is ``lod.card_width`` cells wide and stands for its cell's blades, so the atlas holds
    exactly those: their colour ramp (the blade material's, with each blade's shade), shape and
    coverage are the blades'. Each blade keeps its full width and its whole droop (to the side its
    lean points to): seen from a direction v, a blade shows w |sin(v - facing)| of its width (and
    |cos| of its droop) and the card |cos(v - card normal)| of its area; averaged over the
    directions all are 2/pi, so the card's coverage must be the blades' whole area over the card's
    (``card_coverage``). Sizes projected onto the card would count that foreshortening twice (the
    cards 1.57 times too sparse); what a long droop carries past the card's edge is given back by
    widening that variant's strips until its coverage is the blades' area. The variant's height
    spans its card's height (``card_height``)."""
    block = sample_blades(params)
    num = int(params.field.blades_per_cell)
    image = np.empty((size, variants * size, 4), np.float32)
    for k in range(variants):
        cell = k % block.cell_center.shape[0]
        blades = list(range(cell * num, (cell + 1) * num))
        target = _blade_share(params, block, cell, blades)
        widen = 1.0
        for _ in range(3):  # coverage is about linear in the width: converges in a step or two
            rgb, alpha = _draw_variant(params, block, cell, blades, size, widen)
            covered = float(alpha.mean())
            if covered <= 0.0 or abs(covered - target) <= 0.02 * target:
                break
            widen = min(4.0, widen * target / covered)
        image[:, k * size:(k + 1) * size, :3] = rgb
        image[:, k * size:(k + 1) * size, 3] = alpha
    return image


def _blade_share(params: Params, block, cell: int, blades) -> float:
    """Whole area of the cell's blades (tapered strips, face on) over its card's area."""
    card_w = _card_width(params)
    taper = 0.5 * (1.0 + params.blade.tip_width)
    area = sum(taper * float(block.blade_width[b]) * float(block.blade_length[b]) for b in blades)
    return area / (card_w * float(block.card_height[cell]))


def _draw_variant(params: Params, block, cell: int, blades, size: int, widen: float):
    """(rgb (size, size, 3), alpha (size, size)) of one card: its blades drawn over one another."""
    n = int(params.blade.segments)
    card_w = _card_width(params)
    species = Species(params)
    rgb = np.zeros((size, size, 3), np.float64)
    alpha = np.zeros((size, size), np.float64)
    ys = (np.arange(size) + 0.5) / size
    height = float(block.card_height[cell])
    axis = float(block.card_facing[cell])
    a = np.array([np.cos(axis), np.sin(axis)])
    taper = 1.0 - (1.0 - params.blade.tip_width) * np.arange(n + 1) / n
    for b in blades:
        facing = float(block.blade_facing[b])
        lean = 1.0 if float(np.array([np.cos(facing), np.sin(facing)]) @ a) >= 0.0 else -1.0
        seg = float(block.blade_length[b]) / n
        tilt = block.blade_rest_tilt[b].astype(np.float64)
        along = np.concatenate([[0.0], np.cumsum(seg * np.sin(tilt))]) * lean
        up = np.concatenate([[0.0], np.cumsum(seg * np.cos(tilt))])
        root = float((block.blade_root[b, :2] - block.card_center[cell]) @ a)
        u = (root + along) / card_w + 0.5  # 0 .. 1 across the card
        half = 0.5 * widen * float(block.blade_width[b]) * taper / card_w
        tip = species.color[int(block.blade_species[b])].astype(np.float64)
        colour = blade_colour_ramp(tip, np.arange(n + 1) / n) * (0.7 + 0.6 * float(block.blade_shade[b]))
        _draw_strip(rgb, alpha, ys, u, up / height, half, colour)
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
    card units) over a square card image, one row at a time: each row crosses the strip where its
    height v lies between two joints; edges anti-aliased over one pixel."""
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
    col = colour[j] + (colour[j + 1] - colour[j]) * t[:, None]
    xs = (np.arange(size) + 0.5) / size
    cover = np.clip((width[:, None] - np.abs(xs[None, :] - centre[:, None])) * size + 0.5, 0.0, 1.0)
    rgb[rows] = col[:, None, :] * cover[..., None] + rgb[rows] * (1.0 - cover[..., None])
    alpha[rows] = cover + alpha[rows] * (1.0 - cover)


def card_coverage(params: Params) -> tuple[float, float]:
    """(mean alpha of the atlas, the blades' whole area / card area of the same cells): a check
    that the cards cover what their blades cover."""
    atlas = card_atlas(params)
    block = sample_blades(params)
    num = int(params.field.blades_per_cell)
    area = cards = 0.0
    for k in range(CARD_VARIANTS):
        cell = k % block.cell_center.shape[0]
        card_area = _card_width(params) * float(block.card_height[cell])
        cards += card_area
        area += _blade_share(params, block, cell, range(cell * num, (cell + 1) * num)) * card_area
    return float(atlas[..., 3].mean()), area / cards
