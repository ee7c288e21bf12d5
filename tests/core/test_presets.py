"""Species presets (grass_addon/presets.py): valid for the schema and plausible to an artist."""

import numpy as np
import pytest
from windgrass.grass_addon import blade, presets, schema
from windgrass.grass_addon.errors import ParameterError


def _mean_length(rows) -> float:
    weights = np.array([r["weight"] for r in rows])
    return float(np.dot(weights, [r["length"] for r in rows]) / weights.sum())


@pytest.mark.parametrize("name", presets.PRESET_NAMES)
def test_preset_is_a_valid_species_table(name):
    rows = presets.species_rows(name)
    params = presets.apply_preset(schema.defaults(), name)
    assert params.blade.species == rows
    assert params.species() == rows
    assert [set(r) for r in rows] == [{f.key for f in schema.SPECIES_FIELDS}] * len(rows)
    assert len({r["name"] for r in rows}) == len(rows)  # names tell the species apart in the UI list
    assert name in presets.PRESET_HELP
    # round trip through a scene file, as the headless scripts read it
    assert schema.loads_toml(schema.dumps_toml(params)) == params


def test_lawn_is_mown_and_wild_grass_is_tall():
    """Mowing heights of a lawn are 4-8 cm; hay meadows 0.3-0.6 m; wild grass and reeds higher."""
    lawn, meadow, wild = (_mean_length(presets.species_rows(n)) for n in ("lawn", "meadow", "wild"))
    assert 0.04 <= lawn <= 0.08
    assert 0.3 <= meadow <= 0.6
    assert wild > 0.6
    # a mown lawn is even: its length spread is a small fraction of its length
    assert all(r["length_variation"] <= 0.2 * r["length"] for r in presets.species_rows("lawn"))


@pytest.mark.parametrize("name", presets.PRESET_NAMES)
def test_every_preset_species_stands_up_at_rest(name):
    """Under gravity (eqs 1-6) a blade at the largest initial inclination keeps its tip at least
    60 % of its length above the ground: grass at rest stands, it does not lie flat."""
    b = schema.defaults().blade
    alpha = np.radians(b.inclination)
    for row in presets.species_rows(name):
        seg = np.array([row["length"] / b.segments])
        mu = blade.joint_stiffness(np.array([b.root_stiffness * row["stiffness"]]), seg, b.segments,
                                   b.stiffness_offset)
        tilt = blade.rest_tilt(np.array([alpha]), blade.rest_angles(np.array([alpha]), seg, mu, b.density))
        height = float(np.sum(seg[0] * np.cos(tilt[0])))
        assert height >= 0.6 * row["length"], (name, row["name"], height)


def test_unknown_preset_names_the_parameter():
    with pytest.raises(ParameterError) as info:
        presets.species_rows("jungle")
    assert info.value.key == "blade.species"
    assert "lawn" in str(info.value)
