"""The sward seen from afar (paper III.C): the far grass as the field's own blades make it look.

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
  upper part of each blade (the part not hidden by the sward), weighted by its width (the strip
  of ``blade.width_at``) and by species share.

The cards' texture is ``atlas.py``. Numpy only (no Blender); the bridge writes the values into
the materials.
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
    taper = blade.segment_widths(params.blade.tip_width, n)
    seen = block.blade_width.astype(np.float64)[:, None] * taper[None, :] * np.abs(rise)
    return np.minimum(joint[:, :-1], joint[:, 1:]), np.maximum(joint[:, :-1], joint[:, 1:]), seen


def sward_colour(params: Params) -> tuple[float, float, float]:
    """Mean linear RGB of the visible upper part of the field's blades (see module doc)."""
    species = Species(params)
    v = np.linspace(VISIBLE_FROM, 1.0, 64)
    width = blade.width_at(params.blade.tip_width, v)
    ramp = blade_colour_ramp(species.color.astype(np.float64), v)  # (species, 64, 3)
    per_species = (ramp * width[None, :, None]).sum(axis=1) / width.sum()
    return tuple(float(c) for c in species.p @ per_species)


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


def blade_colour_ramp(tip: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The blade material's colour at heights ``v`` (0 root .. 1 tip) for tip colours ``tip``
    (..., 3): a smoothstep from the base colour to the tip colour over v in [0, GRADIENT_END]."""
    u = np.clip(v / GRADIENT_END, 0.0, 1.0)
    s = u * u * (3.0 - 2.0 * u)
    base = np.asarray(BLADE_BASE_COLOUR)
    return base + (np.asarray(tip)[..., None, :] - base) * s[..., None]
