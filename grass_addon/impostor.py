"""Far grass as the grass itself looks from afar (paper III.C): the sward's height and colour.

The far level of detail (eq 10: the ground texture) stands for the blades it replaces, so its
look is computed from them: a sample block of the field's own blades (``blocks.make_block``,
species, lengths, rest shapes) and the blade material's colour ramp (a dark base to the species'
tip colour over the lower 70 % of the blade, ``bridge/materials.py``):

* ``canopy_height``: where a low, grazing view stops seeing through the sward: the height below
  which the blades hide the ground, taken as the mean of the blades' rest tip heights times
  CANOPY_SHARE. The far texture lies on a plane at that height, so at the horizon the field's
  silhouette is the grass's, not the ground's.
* ``sward_colour``: the colour of the blades as a grazing view sees them: the mean colour of the
  upper part of each blade (the part not hidden by the sward), weighted by its width (strips
  taper to ``blade.tip_width``) and by species share.

Numpy only (no Blender); the bridge writes the values into the materials.
"""

from __future__ import annotations

import numpy as np

from .blocks import FieldGrid, Species, make_block
from .schema import Params

BLADE_BASE_COLOUR = (0.018, 0.03, 0.008)  # the blade material's root colour (linear RGB)
GRADIENT_END = 0.7  # the blade material darkens the lower 70 % of the blade towards the root
CANOPY_SHARE = 0.75  # a grazing view sees the sward down to three quarters of the tips' height
VISIBLE_FROM = 0.35  # of a blade's length: the part below is hidden by the sward from afar


def sample_blades(params: Params):
    """A block of the field's own blades (block 0: every block is drawn from the same law)."""
    return make_block(params, FieldGrid.of(params), Species(params), 0)


def tip_heights(params: Params) -> np.ndarray:
    """Rest height of each sample blade's tip (m): sum of l/n cos(tilt) over its segments."""
    block = sample_blades(params)
    n = int(params.blade.segments)
    if block.blade_length.size == 0:
        return block.cell_length * np.cos(block.cell_rest_tilt).mean(axis=1)
    return (block.blade_length[:, None] / n * np.cos(block.blade_rest_tilt)).sum(axis=1)


def canopy_height(params: Params) -> float:
    """Height (m) of the plane that the far texture lies on."""
    return float(CANOPY_SHARE * np.mean(tip_heights(params)))


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
