"""The sward seen from afar (paper III.C): the far grass as the field's own blades make it look.

The far level of detail (eq 10: the ground texture) stands for the blades it replaces, so its
look is computed from them: a sample of the field's own blades (``sample_blades``: blocks of
``blocks.make_block`` spread over the field; species, lengths, rest shapes) and the blade
material's colour ramp (a dark base to the species' tip colour over the lower 70 % of the blade,
``bridge/materials.py``):

* ``canopy_height``: where a low, grazing view stops seeing through the sward: the height below
  which the blades hide the ground, taken as the mean of the blades' rest tip heights times
  CANOPY_SHARE. The far texture lies on a plane at that height, so at the horizon the field's
  silhouette is the grass's, not the ground's.
* ``sward_depth``: how much blade a ray crosses that leaves the field at height z, which makes the
  field's edge against the sky as ragged and see-through as its blades (a fringe rising from the
  canopy plane to the tallest tip, ``sward_top``), in the colour of the blades' parts that stand
  above the canopy plane (``fringe_colour``: tips, lit like the blades, not shaded by others).
* ``sward_look``: the colour of the sward seen from a view descending with slope s: a grazing
  view meets the lit upper parts of the blades, a steeper one sees deeper, into the blades'
  shade and their dark roots, and through the gaps to the floor. At each height z the ray is
  stopped with the chance that tau(z) / s of blade lies above (``sward_depth``); what it meets
  there is the blades' colour at that height lit by the share exp(-tau(z) / LIGHT_SLOPE) of the
  light that reaches it. The canopy takes this colour for the slope of each ray that meets it.
* ``patch_tint`` and ``patch_stands``: a meadow's patches over the field, for the far canopy and
  the cards: the local mix's colour over the mean, and the stand L whose L tau(z / L) stops grazing
  rays as the local stand does (``stand_depth``, from ``stand_profiles``: each species' sample
  blades by their patch scale).

The cards' texture is ``atlas.py``. Numpy only (no Blender); the bridge writes the values into
the materials.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import blade, edit_parts, meadow, tufts
from .blocks import Block, Species, make_blocks
from .grid import FieldGrid
from .schema import Params

BLADE_BASE_COLOUR = (0.018, 0.03, 0.008)  # the blade material's root colour (linear RGB)
# A blade's value shade: its colour times SHADE_LOW + SHADE_SPAN * blade_shade (0..1), 0.7 to 1.3
# times (``shade_value``; the blade material's value node, the atlas and the sward's look alike).
SHADE_LOW = 0.7
SHADE_SPAN = 0.6
# The meadow's floor under the blades (the ground material: dry thatch and green litter in noise).
THATCH_COLOUR = (0.050, 0.042, 0.016)
LITTER_COLOUR = (0.022, 0.040, 0.010)
# A lawn's floor: the dense turf of living shoots under the blades drawn, shaded among themselves
# (a leaf's green reflectance, about 0.12, times the light that reaches into the turf).
TURF_SHADE = (0.034, 0.085, 0.019)
TURF_LIT = (0.050, 0.118, 0.026)
FLOOR_COLOURS = {"thatch": (THATCH_COLOUR, LITTER_COLOUR), "turf": (TURF_SHADE, TURF_LIT)}
GRADIENT_END = 0.7  # the blade material darkens the lower 70 % of the blade towards the root
LEAF_FLOOR_LIGHT = 0.55  # the leaves the ground stands for, in the sward's shade (``ground_colours``)
CANOPY_SHARE = 0.75  # a grazing view sees the sward down to three quarters of the tips' mean height
PROFILE_POINTS = 33  # heights from the ground to the tallest tip at which ``sward_profile`` gives the depth
# Sun and sky reach height z inside the sward through tau(z) / LIGHT_SLOPE of blades, as light
# from 45 degrees up would (fitted, with materials.SWARD_LIGHT, to all-geometry renders of long
# strips seen from slopes 0.013-0.53, in sun and under an overcast sky: 3 % rms, at worst 7 %;
# headless/lod_compare.py --views strip).
LIGHT_SLOPE = 1.0
LOOK_LAYERS = 48  # height layers over which ``sward_look`` sums what a ray meets
# The canopy's colour curve runs over x = s / (s + LOOK_KNEE) of the ray's slope s (0: grazing,
# 1: straight down), which spends most of its points on the low views where the look changes most.
LOOK_KNEE = 0.1
LOOK_POINTS = 33
VIEWPORT_SLOPE = 0.05  # Solid shading shows the far grass as seen from this slope (eye height / distance)
SAMPLE_SIDE = 6  # ``sample_blades`` draws 6 x 6 of the field's blocks (36 patches of a meadow: its mean)
PATCH_PIXELS = 256  # side of the image of the meadow's patches over the whole field (``patch_tint``)
PATCH_SAMPLES = 2  # ... each pixel the mean of 2 x 2 samples (patches a third of a pixel wide blur, not alias)


def floor_colours(params: Params) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The two linear RGB colours of the floor between the blades (``field.floor``), which the
    ground material mixes in noise."""
    return FLOOR_COLOURS[str(params.field.floor)]


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def ground_colours(params: Params) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The two linear RGB colours the ground material shows under the grass drawn: the floor
    (``floor_colours``) under the leaves at the stems' foot, which are drawn only with their stems
    (``tufts.py``): where cards or the far canopy stand for the blades, the ground stands for the
    leaves, each floor colour mixed towards their mean colour seen from above (LEAF_FLOOR_LIGHT of
    it: they lie in the sward's shade, which a viewport without the cards' shadows does not draw)
    by the share of the ground they cover (1 - exp(-tau_h) of their area seen from above,
    ``leaf_layers``)."""
    floor = floor_colours(params)
    _, top, _, top_rgb = leaf_layers(params, np.zeros(1))
    if top[0] <= 0.0:
        return floor
    leaf, cover = LEAF_FLOOR_LIGHT * top_rgb[0] / top[0], 1.0 - float(np.exp(-top[0]))

    def under(f) -> tuple[float, float, float]:
        r, g, b = (float(c) for c in np.asarray(f) + (leaf - np.asarray(f)) * cover)
        return r, g, b

    return under(floor[0]), under(floor[1])


def sample_blades(params: Params) -> Block:
    """The field's own blades as one block. Without patches every block is drawn from the same law
    and block 0 stands for them all (its 768 blades by default); a meadow's patches (metres wide:
    a block lies in one) change the height and mix from block to block, and what the far grass
    and the cards stand for is the field's mean, so its sample holds the blocks of ``sample_ids``
    (block 0 alone showed the default meadow's tallest stems half as often as its field has
    them). Kept for the last field, blade and level-of-detail settings (what a block is made of:
    ``blocks.make_block``), so a change of the wind or the camera does not draw it again."""
    key = _blocks_key(params)
    if _SAMPLE_KEPT.get("key") != key:
        inner = params.replace({"field.edge": 0.0})  # (the field's mean: its thinning edge is no part of it)
        blocks = make_blocks(inner, FieldGrid.of(inner), Species(inner), sample_ids(inner))
        _SAMPLE_KEPT.clear()
        _SAMPLE_KEPT.update(key=key, whole=_joined(blocks))
    return _SAMPLE_KEPT["whole"]


def _blocks_key(params: Params) -> str:
    """The settings a block is made of (``blocks.make_block``: the layout part of ``edit_parts``):
    the key of what is kept from the field's blocks (the sample, the patches' height map)."""
    return edit_parts.digest_of(params, (edit_parts.LAYOUT,))


def sample_ids(params: Params) -> list[int]:
    """Ids of the blocks ``sample_blades`` draws: with patches SAMPLE_SIDE x SAMPLE_SIDE spread
    evenly over the field, corners included (fewer on a field of fewer blocks), block 0 first;
    block 0 alone without."""
    if params.field.patchiness <= 0.0:
        return [0]
    grid = FieldGrid.of(params)
    nx, ny = grid.blocks_x, grid.blocks_y
    picks = np.linspace(0.0, 1.0, SAMPLE_SIDE)
    return sorted({int(round(j * (ny - 1))) * nx + int(round(i * (nx - 1))) for i in picks for j in picks})


_SAMPLE_KEPT: dict = {}


def _joined(blocks: list[Block]) -> Block:
    """One block holding the blades and cells of ``blocks`` (its ground span: theirs together)."""
    def join(name):
        values = [getattr(b, name) for b in blocks]
        if values[0] is None:
            return None
        if name == "z_range":
            return np.array([min(v[0] for v in values), max(v[1] for v in values)], values[0].dtype)
        return np.concatenate(values, axis=0)

    return Block(**{f.name: join(f.name) for f in dataclasses.fields(Block)})


def tip_heights(params: Params) -> np.ndarray:
    """Rest height of each sample blade's tip (m): sum of l/n cos(tilt) over its segments."""
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return blade.tip_height(block.cell_length, block.cell_rest_tilt)
    shares = meadow.segment_shares(int(params.blade.segments), block.blade_length, block.blade_width,
                                   block.blade_flower)
    return blade.tip_height(block.blade_length, block.blade_rest_tilt, shares)


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def canopy_height(params: Params) -> float:
    """Height (m) of the plane that the far texture lies on."""
    return _canopy(tip_heights(params))


def sward_top(params: Params) -> float:
    """Height (m) of the tallest rest tip: the top of the fringe along the field's edge."""
    return float(max(1e-3, tip_heights(params).max()))


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def fringe_top(params: Params) -> float:
    """Height (m) of the fringe along the field's edge: ``sward_top`` in the field's tallest patch
    (``patch_stands``; its profile is read over the local stand's height there)."""
    return sward_top(params) * max(1.0, float(patch_stands(params).max()))


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
    ground = block.cell_center.shape[0] * float(params.field.cell_size) ** 2  # the block's area
    low, high, seen = _segment_spans(params, block)
    return _area_above(low, high, seen, z) / ground


def _area_above(low, high, seen, heights: np.ndarray) -> np.ndarray:
    """(len(heights),) the blade area a horizontal ray sees above each height, 2/pi times each
    segment's width times rise (``seen``) spread evenly between its ``low`` and ``high`` points."""
    above = np.clip((high[None] - heights[:, None, None]) / np.maximum(high - low, 1e-9)[None], 0.0, 1.0)
    return (above * seen[None]).sum(axis=(1, 2)) * (2.0 / np.pi)


def _segment_spans(params: Params, block):
    """(lowest, highest point, width times rise) of every segment of ``block``'s blades at rest,
    each (blades, segments): what a horizontal ray sees of a segment lies between the two. Kept
    with the sample for ``sample_blades``' block (a materials update reads them five times)."""
    if block is _SAMPLE_KEPT.get("whole"):
        if "spans" not in _SAMPLE_KEPT:
            spans = _spans(params, block)
            for array in spans:
                array.flags.writeable = False  # (shared by every reader)
            _SAMPLE_KEPT["spans"] = spans
        return _SAMPLE_KEPT["spans"]
    return _spans(params, block)


def _spans(params: Params, block):
    n = int(params.blade.segments)
    seg = block.blade_length.astype(np.float64)[:, None] * meadow.segment_shares(
        n, block.blade_length, block.blade_width, block.blade_flower)  # a flower's head is short
    rise = seg * np.cos(block.blade_rest_tilt.astype(np.float64))
    joint = np.concatenate([np.zeros((rise.shape[0], 1)), np.cumsum(rise, axis=1)], axis=1)
    widths = meadow.joint_widths(params.blade.tip_width, n, block.blade_head, block.blade_flower)
    taper = 0.5 * (widths[:, :-1] + widths[:, 1:])  # each segment's mean width (heads widen the top)
    seen = block.blade_width.astype(np.float64)[:, None] * taper * np.abs(rise)
    return np.minimum(joint[:, :-1], joint[:, 1:]), np.maximum(joint[:, :-1], joint[:, 1:]), seen


def look_slopes() -> tuple[np.ndarray, np.ndarray]:
    """(x, slopes s) of the canopy's curves over the ray's slope: x = s / (s + LOOK_KNEE) in
    LOOK_POINTS steps, the last straight down."""
    along = np.linspace(0.0, 1.0, LOOK_POINTS)
    slopes = LOOK_KNEE * along / np.maximum(1.0 - along, 1e-9)
    slopes[-1] = 1e6
    return along, slopes


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def sward_look(params: Params, slopes) -> np.ndarray:
    """``_sward_look``, kept for the few settings of the field's layout and look last asked (it
    reads no other setting: an edit of the wind or of the solver costs no new look)."""
    return _sward_look(params, np.atleast_1d(np.asarray(slopes, np.float64)))


def _sward_look(params: Params, slopes) -> np.ndarray:
    """Linear RGB (len(slopes), 3) of the sward as a ray descending with each slope s (rise over
    run, > 0) sees it, not yet scaled by how the scene lights a horizontal plane (see module
    doc). Above height z the ray crosses D(z) = tau(z) / s + tau_h(z) of leaf and blade: their
    area a horizontal ray sees (``sward_depth``) over the slope, plus their area a vertical ray
    sees (``top_depth``: blades bent over, the leaves at the stems' foot lying out), once. Layer
    k between heights z_k < z_k+1 stops the ray with chance exp(-D(z_k+1)) - exp(-D(z_k)) and
    shows what it holds, in the colours of each part by how it faces the ray; the floor shows
    where it gets through, exp(-D(0)). Light from 45 degrees up reaches z through
    tau(z) / LIGHT_SLOPE + tau_h(z)."""
    slopes = np.maximum(np.atleast_1d(np.asarray(slopes, np.float64)), 1e-6)[:, None]
    side, top, side_rgb, top_rgb = sward_layers(params)
    depth = side[None] / slopes + top[None]  # (slopes, edges)
    meets = np.exp(-depth[:, 1:]) - np.exp(-depth[:, :-1])  # (slopes, layers)
    d_side, d_top = side[:-1] - side[1:], top[:-1] - top[1:]  # (layers,)
    seen_side, seen_top = d_side[None] / slopes, np.broadcast_to(d_top[None], meets.shape)
    colours = ((seen_side[..., None] * side_rgb[None] + seen_top[..., None] * top_rgb[None])
               / np.maximum(seen_side + seen_top, 1e-12)[..., None])  # (slopes, layers, 3)
    light = side / LIGHT_SLOPE + top
    lit = np.exp(-0.5 * (light[1:] + light[:-1]))
    floor = np.mean(floor_colours(params), axis=0) * np.exp(-light[0])
    return np.einsum("sl,slc->sc", meets * lit[None], colours) + np.exp(-depth[:, :1]) * floor


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def sward_layers(params: Params):
    """``_layers`` at LOOK_LAYERS + 1 heights from the ground to ``sward_top``: what every slope's
    look is made of, worked out once for all the slopes asked (the viewport's and the material's)."""
    return _layers(params, np.linspace(0.0, sward_top(params), LOOK_LAYERS + 1))


def _layers(params: Params, edges: np.ndarray):
    """(side (E,), top (E,), side colours (L, 3), top colours (L, 3)) of the sward at the heights
    ``edges``: the area above each that a horizontal and a vertical ray sees (per square metre of
    ground: the blades' and the leaves' at the stems' foot, ``leaf_layers``), and the mean colour
    of what each layer between two edges shows either ray."""
    side, top = sward_depth(params, edges), top_depth(params, edges)
    blade_rgb = _layer_colours(params, edges)
    leaf_side, leaf_top, leaf_side_rgb, leaf_top_rgb = leaf_layers(params, edges)

    def mixed(blade_depth, leaf_depth, leaf_rgb):
        a, b = blade_depth[:-1] - blade_depth[1:], leaf_depth[:-1] - leaf_depth[1:]
        rgb = leaf_rgb[:-1] - leaf_rgb[1:]
        return (a[:, None] * blade_rgb + rgb) / np.maximum(a + b, 1e-12)[:, None]

    return (side + leaf_side, top + leaf_top, mixed(side, leaf_side, leaf_side_rgb),
            mixed(top, leaf_top, leaf_top_rgb))


def top_depth(params: Params, heights: np.ndarray) -> np.ndarray:
    """tau_h(z): the blades' area above each height z (m) that a vertical ray sees, per square
    metre of ground: each segment's width times its run (its length times sin tilt) at rest."""
    z = np.asarray(heights, np.float64)
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return np.zeros_like(z)
    ground = block.cell_center.shape[0] * float(params.field.cell_size) ** 2
    low, high, seen = _segment_spans(params, block)
    tilt = block.blade_rest_tilt.astype(np.float64)
    run = seen * np.abs(np.tan(np.minimum(tilt, 1.5)))  # width * rise * tan(tilt) = width * run
    return _area_above(low, high, run, z) * (np.pi / 2.0) / ground  # (_area_above: 2/pi of what it sums)


def leaf_layers(params: Params, edges: np.ndarray):
    """The leaves at the sample stems' foot (``tufts``) as the sward's layers count them: (side
    (E,), top (E,)) their area above each of ``edges`` that a horizontal and a vertical ray sees
    per square metre of ground, and (E, 3) each of those areas times its colour (the blade
    material's: the species' colour, straw on a dead leaf, each leaf's shade), summed."""
    z = np.asarray(edges, np.float64)
    out = np.zeros((2, len(z))), np.zeros((2, len(z), 3))
    block = sample_blades(params)
    rows = params.species()
    if block.blade_length.size == 0 or not tufts.leafy(rows).any():
        return out[0][0], out[0][1], out[1][0], out[1][1]
    ground = block.cell_center.shape[0] * float(params.field.cell_size) ** 2
    kind = block.blade_species.astype(np.int64)
    length = tufts.leaf_lengths(rows, kind, block.blade_length, block.blade_alive).astype(np.float64)
    dry = min(1.0, 4.0 * float(params.blade.dry_tips))
    base = np.asarray(BLADE_BASE_COLOUR, np.float64)
    for k, row in enumerate(rows):
        mine = (kind == k) & (length > 0.0)
        if row.get("leaves", "none") not in tufts.LEAF_SHAPES or not mine.any():
            continue
        p = tufts.profile(row["leaves"], GRADIENT_END, SHADE_LOW, SHADE_SPAN)
        size = length[mine]
        at = z[None, :] / size[:, None]  # (stems, E) in each tuft's unit frame
        colour = np.asarray(row["color"], np.float64)
        tips = (colour, colour + (np.asarray(tufts.STRAW) - colour) * dry)
        for view, (area, part_base, part_tip) in enumerate(((p.side, p.side_base, p.side_tip),
                                                            (p.top, p.top_base, p.top_tip))):
            for state in (0, 1):  # live, dead
                out[0][view] += _summed(area[state], at, p.heights, size) / ground
                out[1][view] += (_summed(part_base[state], at, p.heights, size)[:, None] * base
                                 + _summed(part_tip[state], at, p.heights, size)[:, None] * tips[state]) / ground
    return out[0][0], out[0][1], out[1][0], out[1][1]


def _summed(values: np.ndarray, at: np.ndarray, heights: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(E,) a unit tuft's tabulated ``values`` (above each of ``heights``) at the heights ``at``
    (stems, E) of each stem's frame, scaled to its tuft (areas grow with its size squared), summed."""
    return (np.interp(at, heights, values, right=0.0) * (size * size)[:, None]).sum(axis=0)


def _layer_colours(params: Params, edges: np.ndarray) -> np.ndarray:
    """Mean linear RGB (layers, 3) of the blade area between consecutive ``edges`` (heights), as a
    horizontal ray sees it (width times rise): each segment in the blade material's colour at its
    middle, with each blade's shade (as the card atlas draws them)."""
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return np.zeros((len(edges) - 1, 3))
    low, high, seen = _segment_spans(params, block)
    inside = np.clip((np.minimum(high[None], edges[1:, None, None]) - np.maximum(low[None], edges[:-1, None, None]))
                     / np.maximum(high - low, 1e-9)[None], 0.0, 1.0)
    weight = inside * seen[None]  # (layers, blades, segments)
    # each segment's colour at its area's centroid (a head widens its top: its colour weighs more)
    w = meadow.joint_widths(params.blade.tip_width, int(params.blade.segments), block.blade_head, block.blade_flower)
    colour = _segment_colours(params, block, (w[:, :-1] + 2.0 * w[:, 1:]) / (3.0 * (w[:, :-1] + w[:, 1:])))
    total = np.einsum("lbs,bsc->lc", weight, colour)
    return total / np.maximum(weight.sum(axis=(1, 2)), 1e-12)[:, None]


def _segment_colours(params: Params, block, at) -> np.ndarray:
    """Linear RGB (blades, segments, 3) of each segment at the share ``at`` of its length (a
    number or (blades, segments)), in the blade material's ramp with each blade's shade."""
    n = int(params.blade.segments)
    species, kind = Species(params), block.blade_species.astype(np.int64)
    joints = meadow.joint_colours(n, species.color[kind], species.head_color[kind], block.blade_dry,
                                  block.blade_head, block.blade_flower).astype(np.float64)  # heads, dry tips
    at = np.broadcast_to(np.asarray(at, np.float64), (len(kind), n))
    ends = meadow.segment_colours(joints, block.blade_flower).astype(np.float64)  # a flower's head wholly
    tip = ends[:, :, 0] + (ends[:, :, 1] - ends[:, :, 0]) * at[..., None]
    return colour_ramp(tip, (np.arange(n) + at) / n) * shade_value(block.blade_shade)[:, None, None]


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def fringe_colour(params: Params) -> tuple[float, float, float]:
    """Mean linear RGB of the blades' parts above the canopy plane, weighted by the area that a
    horizontal ray sees (width times rise), in the blade material's colours with each blade's
    shade (as the card atlas draws them)."""
    block = sample_blades(params)
    if block.blade_length.size == 0:
        species = Species(params)
        r, g, b = (float(c) for c in species.p @ species.color)
        return r, g, b
    weight, colour = _fringe(params, block)
    r, g, b = (float(c) for c in (colour * weight[..., None]).sum(axis=(0, 1)) / weight.sum())
    return r, g, b


def _fringe(params: Params, block) -> tuple[np.ndarray, np.ndarray]:
    """(weight (blades, segments), colour (blades, segments, 3)) of the sample blades' parts above
    the canopy plane: the area a horizontal ray sees of each (all of it where nothing stands above
    the plane), and its colour at the middle height of that part."""
    low, high, seen = _segment_spans(params, block)
    above = np.clip((high - canopy_height(params)) / np.maximum(high - low, 1e-9), 0.0, 1.0)
    weight = seen * above
    if weight.sum() <= 0.0:
        weight = seen  # nothing above the plane: the blades' mean
    # the upper part of each segment (above the plane) at its middle height along the blade
    return weight, _segment_colours(params, block, 1.0 - 0.5 * above)


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def sward_profile(params: Params, points: int = PROFILE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(heights from the ground to ``sward_top``, ``sward_depth`` at each): what the canopy
    material interpolates (``materials.canopy_material``)."""
    heights = np.linspace(0.0, sward_top(params), points)
    return heights, sward_depth(params, heights)


def _canopy(tips: np.ndarray) -> float:
    return float(CANOPY_SHARE * np.mean(tips))


def shade_value(shade: np.ndarray) -> np.ndarray:
    """(...) float64 the factor on each blade's colour of its value shade ``shade`` (0..1)."""
    return SHADE_LOW + SHADE_SPAN * np.asarray(shade, np.float64)


def colour_ramp(tip: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The blade material's colour (..., 3) at heights ``v`` (..., 0 root .. 1 tip) for the tip
    colours ``tip`` (..., 3) there: a smoothstep from the base colour to the tip colour over v in
    [0, GRADIENT_END]."""
    u = np.clip(np.asarray(v) / GRADIENT_END, 0.0, 1.0)
    s = u * u * (3.0 - 2.0 * u)
    base = np.asarray(BLADE_BASE_COLOUR)
    return base + (np.asarray(tip) - base) * s[..., None]


def species_looks(params: Params) -> tuple[np.ndarray, np.ndarray]:
    """((K, 3) linear RGB, (K,)) each species' colour as the far canopy shows it (its blades' parts
    above the canopy plane, as ``fringe_colour``: heads, dry tips and shades included) and how much
    of it a blade shows (that area, the mean of its sample blades; a species without one takes
    its plain colour and the mean area)."""
    species = Species(params)
    block = sample_blades(params)
    colours = species.color.astype(np.float64).copy()
    areas = np.zeros(len(species.p))
    if block.blade_length.size == 0:
        return colours, np.ones(len(species.p))
    weight, colour = _fringe(params, block)
    kind = block.blade_species.astype(np.int64)
    for k in range(len(species.p)):
        mine = kind == k
        total = weight[mine].sum()
        if total > 0.0:
            colours[k] = (colour[mine] * weight[mine][..., None]).sum(axis=(0, 1)) / total
            areas[k] = total / mine.sum()
    areas[areas == 0.0] = weight.sum(axis=1).mean()
    return colours, areas


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def patch_tint(params: Params, pixels: int = PATCH_PIXELS) -> np.ndarray:
    """(pixels, pixels, 3) float32 over the whole field (row 0 at its low-y edge, as Blender's pixel
    rows): how the meadow's patches tint the far grass there. The look of the local species mix
    (``meadow.species_weights``: each species' share, times how much of it shows, times its colour;
    ``species_looks``) over the field's mean of it, so the far canopy and the cards keep their
    mean colour; ones without patches or with one species."""
    if params.field.patchiness <= 0.0:
        return np.ones((pixels, pixels, 3), np.float32)
    return _patch_maps(params, pixels)[0]  # (ones with one species: ``_paint_patches``)


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def patch_stands(params: Params, pixels: int = PATCH_PIXELS) -> np.ndarray:
    """(pixels, pixels) float32 over the whole field (rows as ``patch_tint``'s): the stand there
    as the far canopy's edge draws it, L in L tau(z / L) (``materials._sward_edge_opacity``: the
    field's mean profile ``sward_depth`` for blades L times as long); ones without patches.

    L is fitted to the local stand's own profile (``stand_depth``: the patches' length scale
    and species mix there), so a stand of short grass lets more sky through than a tall one,
    and one of the mix's sparser species more than one of its bushier ones at the same height.
    The fit makes the chance a grazing ray is stopped, 1 - exp(-tau / s), the closest it can at
    every height for the slopes ``STAND_SLOPES``."""
    if params.field.patchiness <= 0.0:
        return np.ones((pixels, pixels), np.float32)
    return _patch_maps(params, pixels)[1]


def _patch_maps(params: Params, pixels: int) -> tuple[np.ndarray, np.ndarray]:
    """(tint, stands) of ``patch_tint`` and ``patch_stands``, painted in one pass over the field (the
    species mix evaluated once for both) and kept for the last field, blade and LOD settings, as
    the sample: the ground and the patch image both read them."""
    key = (_blocks_key(params), pixels)
    if _PATCHES_KEPT.get("key") != key:
        _PATCHES_KEPT.update(key=key, maps=_paint_patches(params, pixels))
    return _PATCHES_KEPT["maps"]


_PATCHES_KEPT: dict = {}
STAND_SLOPES = (0.02, 0.05, 0.1, 0.2)  # rays over the far edge from eyes 1-6 m up, 20-100 m away
STAND_RANGE = (0.2, 2.0)  # the stands L that ``patch_stands`` chooses from, in steps of STAND_STEP
STAND_STEP = 0.01
STAND_HEIGHTS = 32  # ``stand_depth``'s heights from the ground to twice the sample's tallest tip
SCALE_BINS = 5  # ``stand_profiles`` sorts each species' sample blades into this many bins of patch scale
STAND_SCALES = 256  # ... and tabulates each species' stand at this many scales (a point takes the nearest)
UNIT_HEIGHTS = 192  # ... from one blade's depth at this many heights (at scale 1)


def _paint_patches(params: Params, pixels: int) -> tuple[np.ndarray, np.ndarray]:
    species = Species(params)
    tinted = len(species.p) >= 2
    colours, areas = species_looks(params) if tinted else (None, None)
    fit_here = _samples_across(params, pixels) < pixels * PATCH_SAMPLES  # a small field: fit L where sampled

    def values(xy):  # (n, 2) -> (n, 3 + Z): the mix's look, then the stand's depth (or its L, fitted here)
        weights = meadow.species_weights(xy, params, species.p)
        depth = _stand_depth(params, xy, weights)
        stand = fit_stands(params, depth)[:, None] if fit_here else depth
        if weights is None or areas is None or colours is None:
            return stand
        shown = weights * areas[None, :]
        return np.concatenate([(shown @ colours) / shown.sum(axis=1, keepdims=True), stand], axis=1)

    maps = _over_field(params, pixels, values)
    look, stand = (maps[..., :3], maps[..., 3:]) if tinted else (np.ones((pixels, pixels, 3)), maps)
    tint = (look / look.mean(axis=(0, 1))).astype(np.float32)
    if not fit_here:  # a large field: fit L to each pixel's mean profile
        stand = fit_stands(params, stand.reshape(pixels * pixels, -1)).reshape(pixels, pixels, 1)
    stands = stand[..., 0].astype(np.float32)
    tint.setflags(write=False)  # (kept: every reader gets these arrays)
    stands.setflags(write=False)
    return tint, stands


def stand_heights(params: Params) -> np.ndarray:
    """The heights (m) at which ``stand_depth`` and ``fit_stands`` compare profiles: the ground
    to twice the sample's tallest tip."""
    return np.linspace(0.0, 2.0 * sward_top(params), STAND_HEIGHTS)


def fit_stands(params: Params, depths: np.ndarray) -> np.ndarray:
    """(n,) the L of STAND_RANGE whose L tau(z / L) (the profile the canopy draws: ``sward_profile``
    between its points) stops grazing rays (the slopes STAND_SLOPES) the most like each of
    ``depths`` (n, Z) at ``stand_heights``: the least squared difference of 1 - exp(-tau / s) over
    the heights and slopes."""
    heights, (points, tau) = stand_heights(params), sward_profile(params)
    stands = np.arange(STAND_RANGE[0], STAND_RANGE[1] + 0.5 * STAND_STEP, STAND_STEP)
    family = stands[:, None] * np.interp(heights[None, :] / stands[:, None], points, tau, right=0.0)
    slopes = np.asarray(STAND_SLOPES)[:, None, None]

    def stopped(depth):  # (n, Z) -> (n, slopes * Z)
        return (1.0 - np.exp(-depth[None] / slopes)).transpose(1, 0, 2).reshape(len(depth), -1)

    a, b = stopped(np.asarray(depths, np.float64)), stopped(family)
    cost = (b * b).sum(axis=1)[None, :] - 2.0 * a @ b.T  # |a - b|^2 less |a|^2, the same for every L
    return stands[cost.argmin(axis=1)]


def stand_depth(params: Params, xy: np.ndarray) -> np.ndarray:
    """(n, Z) the silhouette depth tau(z) (as ``sward_depth``) at ``stand_heights`` of the stand
    the meadow grows at each of ``xy`` (n, 2) m: its species mix (``meadow.species_weights``) of
    blades scaled by the patches' length (``meadow.length_scale``), each species' blades of that
    scale as the sample's (``stand_profiles``, at the nearest of its scales)."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    return _stand_depth(params, xy, meadow.species_weights(xy, params, Species(params).p))


def _stand_depth(params: Params, xy: np.ndarray, weights: np.ndarray | None) -> np.ndarray:
    species = Species(params)
    shares = np.broadcast_to(species.p / species.p.sum(), (len(xy), len(species.p))) if weights is None \
        else weights / weights.sum(axis=1, keepdims=True)
    scales, table = stand_profiles(params)
    step = (scales[-1] - scales[0]) / max(len(scales) - 1, 1)
    nearest = np.clip(np.rint((meadow.length_scale(xy, params) - scales[0]) / max(step, 1e-12)), 0, len(scales) - 1)
    nearest = nearest.astype(np.int64)
    out = np.zeros((len(xy), table.shape[2]), np.float32)
    for k in range(len(species.p)):
        out += shares[:, k, None].astype(np.float32) * table[k, nearest]
    return out


def stand_profiles(params: Params) -> tuple[np.ndarray, np.ndarray]:
    """(scales (M,), depths (species, M, Z)): ``sward_depth`` at ``stand_heights`` of a stand of
    each species alone, its blades the patches' scale s times as long, for M scales over all the
    patches make. A stand of scale s is the sample's blades of that species and about that scale (the
    bins of SCALE_BINS: a long blade leans more, so stands are not plain scaled copies of each
    other) scaled from their own scale to s: heights and area s / s_b times theirs. Kept with the
    sample."""
    block, species = sample_blades(params), Species(params)
    if "profiles" in _SAMPLE_KEPT:  # (drawing the sample again clears it)
        return _SAMPLE_KEPT["profiles"]
    scale = meadow.length_scale(block.blade_root[:, :2].astype(np.float64), params)
    kind = block.blade_species.astype(np.int64)
    bins = min(SCALE_BINS, max(2, len(scale) // 200))
    edges = np.quantile(scale, np.linspace(0.0, 1.0, bins + 1)) if len(scale) else np.linspace(0.9, 1.1, bins + 1)
    binned = np.clip(np.searchsorted(edges, scale, side="right") - 1, 0, bins - 1)
    centres = np.array([np.median(scale[binned == j]) if np.any(binned == j) else edges[j] for j in range(bins)])
    centres = np.maximum.accumulate(centres + 1e-9 * np.arange(bins))  # (increasing)
    heights = stand_heights(params)
    # every scale the patches make (beyond the outer bins' medians their blades are scaled further)
    reach = meadow.PATCH_LENGTH * float(params.field.patchiness)
    scales = np.linspace(min(float(scale.min()), 1.0 - reach), max(float(scale.max()), 1.0 + reach), STAND_SCALES)
    scales = np.maximum(scales, 0.05)
    unit = np.linspace(0.0, heights[-1] / max(float(scales[0]), 0.05), UNIT_HEIGHTS)  # heights at scale 1
    low, high, seen = _segment_spans(params, block)
    per_bin = np.zeros((len(species.p), bins, len(unit)))  # the depth of one blade at scale 1
    for k in range(len(species.p)):
        for j in range(bins):
            mine = (kind == k) & (binned == j)
            if not np.any(mine):
                mine = kind == k  # (a rare species missing from a bin: its blades of every scale)
            if not np.any(mine):
                continue
            s = scale[mine, None]
            per_bin[k, j] = _area_above(low[mine] / s, high[mine] / s, seen[mine] / s, unit) / mine.sum()
    density = len(kind) / max(block.cell_center.shape[0] * float(params.field.cell_size) ** 2, 1e-12)
    at = np.interp(scales, centres, np.arange(bins, dtype=np.float64))
    lo = np.minimum(at.astype(np.int64), bins - 2)
    f = at - lo
    table = np.zeros((len(species.p), len(scales), len(heights)))
    for m, stand in enumerate(scales):
        u = heights / stand
        for k in range(len(species.p)):
            below, above = (np.interp(u, unit, per_bin[k, lo[m] + i]) for i in (0, 1))
            table[k, m] = density * stand * ((1.0 - f[m]) * below + f[m] * above)
    table = table.astype(np.float32)  # (``stand_depth`` gathers rows of it for every point of a field)
    _SAMPLE_KEPT["profiles"] = (scales, table)
    return scales, table


def _samples_across(params: Params, pixels: int) -> int:
    """How many samples ``_over_field`` takes across the field: PATCH_SAMPLES a pixel, or 8 a
    patch where that is fewer (at least 16)."""
    size = float(max(FieldGrid.of(params).size))
    return int(min(pixels * PATCH_SAMPLES, max(16, np.ceil(8.0 * size / float(params.field.patch_size)))))


def _over_field(params: Params, pixels: int, values) -> np.ndarray:
    """(pixels, pixels, C) a function ``values`` ((n, 2) points in metres -> (n, C)) over the whole
    field, row 0 at its low-y edge: each pixel the mean of PATCH_SAMPLES x PATCH_SAMPLES samples,
    or, where 8 samples a patch are fewer, bilinear between those at the pixels' centres (a small
    field costs little)."""
    grid = FieldGrid.of(params)
    size, origin = np.asarray(grid.size), grid.origin
    m = _samples_across(params, pixels)
    t = (np.arange(m) + 0.5) / m
    xs, ys = np.meshgrid(origin[0] + t * size[0], origin[1] + t * size[1])
    look = values(np.column_stack([xs.ravel(), ys.ravel()]))
    look = look.reshape(m, m, look.shape[-1])
    if m == pixels * PATCH_SAMPLES:
        return look.reshape(pixels, PATCH_SAMPLES, pixels, PATCH_SAMPLES, -1).mean(axis=(1, 3))
    at = np.clip((np.arange(pixels) + 0.5) / pixels * m - 0.5, 0.0, m - 1.0)
    lo = np.minimum(at.astype(int), m - 2)
    f = (at - lo)[:, None, None]
    rows = look[lo] * (1.0 - f) + look[lo + 1] * f  # (pixels, m, C)
    f = f.reshape(1, -1, 1)
    return rows[:, lo] * (1.0 - f) + rows[:, lo + 1] * f


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def grain_seen(params: Params, slopes) -> np.ndarray:
    """(len(slopes),) the share of the tussocks' grain (``tussock_grain``'s contrast) that a pixel
    of rays descending with each slope s shows. Such a ray crosses the sward from its top and is
    stopped where tau(z) / s of blade lies above it (``sward_depth``, as ``sward_look``), or at the
    floor: a steep ray within one tussock, a grazing one anywhere along metres of them (from 2.5 m
    up at 30 m, along 2-3 m: five tussocks of 0.45 m). The pixel is the mean of the tussocks its
    rays stop in, each by the chance p_i that they stop there, so the grain's contrast is
    multiplied by sqrt(sum p_i^2) (tussocks as intervals of the clump size along the ray,
    averaged over where they start); a texture lit tussock by tussock drew the far canopy in
    streaks the geometry does not show (``dev.py lod --views strip``)."""
    f = params.field
    size = float(f.clump_size) if f.clumping > 0.0 else float(f.cell_size)
    heights, depth = sward_profile(params)
    top = float(heights[-1])
    slopes = np.maximum(np.atleast_1d(np.asarray(slopes, dtype=np.float64)), GRAIN_SLOPE_MIN)
    out = np.ones(len(slopes))
    if top <= 0.0:
        return out
    steps, phases = 2048, (np.arange(16) + 0.5) / 16.0
    for k, s in enumerate(slopes):
        run = top / s  # horizontal length of the ray over the sward, top to floor
        x = np.linspace(0.0, run, steps + 1)
        alive = np.exp(-np.interp(top - s * x, heights, depth) / s)
        stop = np.append(-np.diff(alive), alive[-1])  # the chance of each step, the floor's last
        at = np.append(0.5 * (x[:-1] + x[1:]), run) / size
        tussock = np.floor(at[None, :] + phases[:, None]).astype(np.int64)  # (phase, step)
        bins = int(tussock.max()) + 1
        chances = np.bincount((tussock + bins * np.arange(len(phases))[:, None]).ravel(),
                              weights=np.broadcast_to(stop, tussock.shape).ravel(), minlength=bins * len(phases))
        out[k] = np.sqrt(float((chances ** 2).sum()) / len(phases))
    return out


GRAIN_SLOPE_MIN = 1e-3  # ``grain_seen`` takes rays less steep as this steep (their run is metres anyway)
GRAIN_SIDE = 16  # ``tussock_grain`` lays out a square of this many tussocks a side
GRAIN_PURPOSE = 41  # np.random.default_rng([seed, 41]) lays it out
GRAIN_MAX = 0.5  # the grain's contrast is at most this (a bound on odd settings)


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def tussock_grain(params: Params) -> tuple[float, float]:
    """(size (m), contrast) of the grain that the field's tussocks give the far grass. A tussock
    (the blades whose roots share a clump centre, ``meadow.clump_centres``; a cell of an even
    field) shows the lit blade of its blades' parts above the canopy plane (the area a horizontal
    ray sees times its brightness, ``_fringe``). Roots are laid out as the field lays them
    (``field.blades_per_cell`` in each cell, pulled to their tussocks) over a square of GRAIN_SIDE
    tussocks, each blade one of the sample's: the contrast is the spread (standard
    deviation over mean) of what the whole tussocks show: large and small, dense and sparse,
    flowering and green. Blender's Voronoi cells of this size, each brightened by a random value
    of this spread times the share a ray's slope shows (``grain_seen``: a grazing ray runs through
    several tussocks), give the far canopy a meadow's grain; pixels average it away further off,
    as they do the field's (``materials.canopy_material``)."""
    f = params.field
    size = float(f.clump_size) if f.clumping > 0.0 else float(f.cell_size)
    block = sample_blades(params)
    if block.blade_length.size == 0:
        return size, 0.0
    weight, colour = _fringe(params, block)
    light = (weight[..., None] * colour).sum(axis=1) @ np.array([0.2126, 0.7152, 0.0722])
    rng = np.random.default_rng([int(f.seed), GRAIN_PURPOSE])
    cell, per_cell = float(f.cell_size), int(f.blades_per_cell)
    n = int(np.ceil(GRAIN_SIDE * size / cell))
    corners = np.stack(np.meshgrid(np.arange(n), np.arange(n)), axis=-1).reshape(-1, 2) * cell
    roots = np.repeat(corners, per_cell, axis=0) + rng.random((n * n * per_cell, 2)) * cell
    centre = meadow.clump_centres(roots, int(f.seed), size) if f.clumping > 0.0 else \
        (np.floor(roots / size) + 0.5) * size
    inside = np.all((centre >= size) & (centre <= n * cell - size), axis=1)  # whole tussocks only
    _, tussock = np.unique(np.round(centre[inside] / (1e-3 * size)).astype(np.int64), axis=0, return_inverse=True)
    per = np.bincount(tussock.ravel(), weights=light[rng.integers(0, len(light), int(inside.sum()))])
    if len(per) < 4 or per.mean() <= 0.0:
        return size, 0.0
    return size, float(min(GRAIN_MAX, per.std() / per.mean()))


# --------------------------------------------------------------------------------------------
# The far canopy's flowers, seen from above


SPECKLE_SLOPES = (0.15, 0.45)  # the ray's slope over which the canopy's flowers come in (from above;
# at lower, grazing slopes the sward's look, ``sward_look``, holds the flowers' share in its colour)


@edit_parts.remembered((edit_parts.LAYOUT, edit_parts.LOOK))
def flower_speckles(params: Params) -> tuple[float, float, list[tuple[float, tuple]]]:
    """What the far canopy draws of the field's flowers (and seed heads) seen from above, each
    flower a disc of its own: (flowers per m² of ground, their radius in m (the mean over their
    areas), [(the running share of the flowers up to that species, its head colour)]). A
    flower's width is its species' ``head_size`` times its stem's width; the count, the stems
    per m² times each species' share and its ``heads`` share. The canopy places one flower in
    each cell of a Voronoi grid of that density (``materials.canopy_material``), so the area
    the flowers cover is their real share of the ground (each radius r on 1 / density m²)."""
    species = Species(params)
    f = params.field
    stems = float(f.blades_per_cell) / float(f.cell_size) ** 2
    share = species.p * species.heads * species.flower
    total = float(share.sum())
    if total <= 0.0 or stems <= 0.0:
        return 0.0, 0.0, []
    radius = 0.5 * species.head_size * species.width
    mean_radius = float(np.sqrt((share * radius ** 2).sum() / total))
    running = np.cumsum(share) / total
    colours = [(float(running[k]), tuple(float(c) for c in species.head_color[k]))
               for k in np.flatnonzero(share > 0.0)]
    return stems * total, mean_radius, colours
