"""Far grass computed from the field's own blades (impostor.py): the card atlas covers what the
cell's blades cover, in the blade material's colours; the far canopy's height and colour are the
sward's."""

import numpy as np
import pytest
from windgrass.grass_addon import impostor, presets, schema


@pytest.fixture(params=["default", "meadow"])
def params(request):
    p = schema.defaults().replace({"field.blades_per_cell": 3})
    return p if request.param == "default" else presets.apply_preset(p, "meadow")


def test_cards_cover_what_their_blades_cover(params):
    """A card stands for its cell's blades: the atlas's mean opacity is the blades' projected
    area (width across the card times height, tapering) over the card's area."""
    mean_alpha, blade_share = impostor.card_coverage(params)
    assert 0.01 < blade_share < 0.5
    assert mean_alpha == pytest.approx(blade_share, rel=0.25)


def test_card_atlas_is_the_blades_colours_rooted_at_the_bottom(params):
    atlas = impostor.card_atlas(params)
    size = impostor.CARD_PIXELS
    assert atlas.shape == (size, impostor.CARD_VARIANTS * size, 4) and atlas.dtype == np.float32
    alpha = atlas[..., 3]
    rows = alpha.mean(axis=1)
    assert rows[: size // 8].mean() > rows[size // 2: 5 * size // 8].mean()  # blades taper, tips droop
    # opaque pixels take the blade material's ramp: from the dark base to a shaded species colour
    colours = impostor.Species(params).color
    rgb = atlas[..., :3][alpha > 0.5]
    assert rgb.size and np.all(rgb <= 1.3 * colours.max(axis=0) + 1e-6)
    assert np.all(rgb >= 0.7 * np.asarray(impostor.BLADE_BASE_COLOUR) - 1e-6)
    assert (rgb[:, 1] >= rgb[:, 2]).mean() > 0.95  # green over blue, like every species colour
    # each variant shows different blades
    variants = alpha.reshape(size, impostor.CARD_VARIANTS, size).transpose(1, 0, 2)
    assert not np.array_equal(variants[0], variants[1])


def test_far_canopy_is_the_swards_height_and_colour(params):
    tips = impostor.tip_heights(params)
    height = impostor.canopy_height(params)
    assert 0.5 * tips.mean() < height < tips.mean() < max(r["length"] for r in params.species()) * 1.5
    colour = np.array(impostor.sward_colour(params))
    species = impostor.Species(params)
    tip = species.p @ species.color
    # the visible upper part of the blades: darker than the tips, lighter than the roots
    assert np.all(colour <= tip + 1e-6) and np.all(colour >= np.asarray(impostor.BLADE_BASE_COLOUR))
    assert np.all(colour >= 0.6 * tip)
