"""The parameter schema: defaults, TOML files, CLI flags and the errors bad input gets."""

import argparse
import math

import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.errors import ParameterError


def test_defaults_are_the_papers_test_scene():
    p = schema.defaults()
    # paper VI: 32x32 patches of 16x16 cells with two blades each = 524,288 blades
    assert (p.field.blocks_x, p.field.blocks_y, p.field.cells_per_block, p.field.blades_per_cell) == (32, 32, 16, 2)
    assert p.field.blocks_x * p.field.blocks_y * p.field.cells_per_block**2 * p.field.blades_per_cell == 524_288
    assert p.blade.segments == 5  # the paper finds 4-6 segments sufficient


def test_every_default_lies_in_its_range():
    for param in schema.PARAMS:
        if param.kind in ("int", "float"):
            assert param.minimum <= param.default <= param.maximum, param.name
        assert param.help, param.name


def test_toml_round_trip_keeps_every_value():
    p = schema.defaults().replace({
        "wind.speed": 6.0, "blade.species": [{"name": "tall", "length": 0.6, "weight": 2.0},
                                             {"name": "short", "length": 0.1}],
        "wind.keys": [{"time": 0.0, "speed": 2.0, "direction": 10.0}, {"time": 5.0, "speed": 8.0, "direction": 90.0}],
    })
    assert schema.loads_toml(schema.dumps_toml(p)) == p


def test_wind_type_brings_its_beaufort_speed_unless_given():
    assert schema.loads_toml('[wind]\ntype = "moderate_breeze"').wind.speed == pytest.approx(6.7)
    assert 5.5 <= schema.WIND_TYPE_SPEED["moderate_breeze"] <= 7.9
    assert 3.4 <= schema.WIND_TYPE_SPEED["gentle_breeze"] <= 5.4
    assert schema.WIND_TYPE_SPEED["calm"] < 0.5
    assert schema.loads_toml('[wind]\ntype = "calm"\nspeed = 2.0').wind.speed == 2.0


@pytest.mark.parametrize("text, key, words", [
    ("[wind]\nspeed = nan", "wind.speed", ["finite", "0 to 60 m/s"]),
    ("[wind]\nspeed = inf", "wind.speed", ["finite", "0 to 60 m/s"]),
    ("[wind]\nspeed = -3.0", "wind.speed", ["out of range", "0 to 60 m/s"]),
    ("[wind]\nspeed = \"fast\"", "wind.speed", ["not a number"]),
    ("[wind]\ntype = \"tornado\"", "wind.type", ["unknown value", "gentle_breeze", "whirlwind"]),
    ("[wind]\nsped = 3.0", "wind.sped", ["unknown key", "speed"]),
    ("[weather]\nrain = 1", "weather", ["unknown section", "wind"]),
    ("[field]\nblocks_x = -2", "field.blocks_x", ["out of range", "1 to 1638400"]),
    ("[field]\nblocks_x = 2.5", "field.blocks_x", ["whole number"]),
    ("[field]\nblocks_x = 1e12", "field.blocks_x", ["out of range"]),
    # 10 km x 10 km (2 x 10^10 blades) is valid; past 16,384 m float32 positions lose millimetres
    ("[field]\nblocks_x = 10241", "field.blocks_x", ["16,386 m", "16,384 m", "1 to 10,240 blocks of 1.6 m"]),
    ("[field]\nblocks_y = 20000\ncells_per_block = 64\ncell_size = 1.0", "field.blocks_y", ["1 to 256 blocks"]),
    ("[simulation]\npreroll = 5.0\nepoch = 2.0", "simulation.epoch", [">= simulation.preroll"]),
    ("[field]\nseed = -1", "field.seed", ["0 to 2147483647"]),
    ("[render]\nframe_end = 2000000", "render.frame_end", ["0 to 1000000"]),
    ("[blade]\nroot_stiffness = 0.0", "blade.root_stiffness", ["1e-07 to 1 N*m^2/rad"]),
    ("[lod]\nenabled = 1", "lod.enabled", ["true/false"]),
    ("[lod]\nblade_near = 10.0\nblade_far = 5.0", "lod.blade_far", [">= lod.blade_near"]),
    ("[camera]\nposition = [1, 2]", "camera.position", ["3 numbers"]),
    ("[render]\nframe_start = 10\nframe_end = 5", "render.frame_end", ["before"]),
    ("[[blade.species]]\nname = \"a\"\nheight = 3", "blade.species[0].height", ["unknown key", "length"]),
    ("[[blade.species]]\nweight = 0.0", "blade.species", ["weights add up to 0"]),
    ("[[wind.keys]]\ntime = 1.0\n[[wind.keys]]\ntime = 0.5", "wind.keys", ["increase"]),
    ("[[wind.keys]]\ntime = 0.0\nspeed = -1.0", "wind.keys[0].speed", ["out of range"]),
    ("wind = 3", "wind", ["must be a table"]),
    ("[wind\nspeed = 3", "config", ["not valid TOML"]),
])
def test_bad_toml_names_the_key_and_the_valid_range(text, key, words):
    with pytest.raises(ParameterError) as info:
        schema.loads_toml(text, source="scene.toml")
    assert info.value.key == key
    message = str(info.value)
    assert message.startswith(key)
    assert "scene.toml" in message
    for word in words:
        assert word in message


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(ParameterError, match="cannot read"):
        schema.load_toml(tmp_path / "nope.toml")


def test_cli_flags_are_generated_from_the_schema():
    parser = argparse.ArgumentParser()
    schema.add_cli_arguments(parser)
    flags = {a for action in parser._actions for a in action.option_strings}
    for param in schema.cli_params():
        assert param.cli_flag in flags
    args = parser.parse_args(["--wind-speed", "7.5", "--field-blocks-x", "4", "--lod-enabled", "false",
                              "--camera-position", "1", "2", "3"])
    p = schema.defaults().replace(schema.cli_overrides(args))
    assert (p.wind.speed, p.field.blocks_x, p.lod.enabled, p.camera.position) == (7.5, 4, False, (1.0, 2.0, 3.0))


@pytest.mark.parametrize("argv, key", [
    (["--wind-speed", "nan"], "wind.speed"),
    (["--field-blocks-x", "-1"], "field.blocks_x"),
    (["--wind-speed", "fast"], "wind.speed"),
    (["--field-blocks-x", "1_000"], "field.blocks_x"),  # float() takes these; a flag does not
    (["--wind-speed", "\uff15"], "wind.speed"),  # a full-width 5
    (["--wind-speed", "0x10"], "wind.speed"),
])
def test_bad_cli_values_name_the_parameter(argv, key):
    parser = argparse.ArgumentParser()
    schema.add_cli_arguments(parser)
    with pytest.raises(ParameterError) as info:
        schema.defaults().replace(schema.cli_overrides(parser.parse_args(argv)))
    assert info.value.key == key


def test_cli_numbers_are_written_as_numbers_are():
    parser = argparse.ArgumentParser()
    schema.add_cli_arguments(parser)
    args = parser.parse_args(["--wind-speed", "+7", "--wind-turbulence", "3.", "--wind-turbulence-scale", ".5",
                              "--blade-root-stiffness", "1e-3"])
    p = schema.defaults().replace(schema.cli_overrides(args))
    assert (p.wind.speed, p.wind.turbulence, p.wind.turbulence_scale, p.blade.root_stiffness) == (7.0, 3.0, 0.5, 1e-3)


def test_params_are_immutable_and_hash_by_value():
    a, b = schema.defaults(), schema.defaults()
    assert a == b and a.digest() == b.digest()
    with pytest.raises(AttributeError):
        a.wind.speed = 3.0
    assert a.replace({"field.seed": 1}).digest() != a.digest()
    assert not math.isnan(a.wind.speed)


def test_changing_the_wind_type_brings_its_preset_unless_given():
    p = schema.defaults().replace({"wind.type": "calm"})
    assert (p.wind.speed, p.wind.turbulence) == (schema.WIND_TYPE_PRESETS["calm"]["speed"],
                                                  schema.WIND_TYPE_PRESETS["calm"]["turbulence"])
    q = schema.defaults().replace({"wind.type": "moderate_breeze", "wind.speed": 7.5})
    assert q.wind.speed == 7.5 and q.wind.turbulence == schema.WIND_TYPE_PRESETS["moderate_breeze"]["turbulence"]
    # re-stating the current type keeps the user's values
    r = schema.defaults().replace({"wind.speed": 5.0}).replace({"wind.type": "gentle_breeze"})
    assert r.wind.speed == 5.0


def test_unreadable_scene_files_are_clear_errors(tmp_path):
    cases = {
        "utf16.toml": ("[field]\nblocks_x = 4\n".encode("utf-16"), "not UTF-8"),
        "binary.toml": (bytes(range(256)) * 4, "not UTF-8"),
        "deep.toml": (b"a = " + b"[" * 50000 + b"]" * 50000, "too deeply"),
    }
    for name, (data, words) in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(ParameterError, match=words) as info:
            schema.load_toml(path)
        assert info.value.key == "config", name
    with pytest.raises(ParameterError, match="is a folder"):
        schema.load_toml(tmp_path)


def test_applies_when_names_a_choice_of_an_enum_of_the_section():
    conditional = [p for p in schema.PARAMS if p.applies_when]
    assert {p.name for p in conditional} >= {"wind.gust_speed", "wind.vortex_speed", "camera.position"}
    for p in conditional:
        key, choice = p.applies_when
        enum = schema.BY_NAME[f"{p.section}.{key}"]
        assert enum.kind == "enum" and choice in enum.choices, p.name


def test_size_density_and_stiffness_in_an_artists_words_set_the_engines_parameters():
    """Issue #28: a field sized in metres, its density in blades per square metre, stiffness as a
    0-1 feel; scene files and flags take them, and the old keys still work."""
    p = schema.loads_toml("[field]\nsize_x = 20.0\nsize_y = 9.0\ndensity = 400\ncell_size = 0.2\n")
    block = p.field.cells_per_block * p.field.cell_size  # 16 cells of 0.2 m: 3.2 m blocks
    assert (p.field.blocks_x, p.field.blocks_y) == (6, 3)  # 20 m -> 19.2 m, 9 m -> 9.6 m: whole blocks
    assert abs(p.field.blocks_x * block - 20.0) <= block / 2 and abs(p.field.blocks_y * block - 9.0) <= block / 2
    assert p.field.blades_per_cell == 16  # 400 blades/m^2 on 0.04 m^2 cells
    # read back in the same words
    views = {v.param.name: v.read(p.to_dict()[v.param.section]) for v in schema.VIEWS}
    assert views["field.size_x"] == pytest.approx(6 * block) and views["field.density"] == pytest.approx(400)
    # stiffness: 0 and 1 are the ends of the range, evenly spaced in log(mu_root)
    low, high = schema.STIFFNESS_FEEL
    assert schema.defaults().replace({"blade.stiffness": 0.0}).blade.root_stiffness == low
    assert schema.defaults().replace({"blade.stiffness": 1.0}).blade.root_stiffness == high
    mid = schema.defaults().replace({"blade.stiffness": 0.5}).blade.root_stiffness
    assert math.isclose(mid, math.sqrt(low * high), rel_tol=1e-3)
    # the old keys
    old = schema.loads_toml("[field]\nblocks_x = 5\nblades_per_cell = 3\n")
    assert (old.field.blocks_x, old.field.blades_per_cell) == (5, 3)
    # both at once is a sentence naming both
    with pytest.raises(ParameterError) as err:
        schema.loads_toml("[field]\nsize_x = 20.0\nblocks_x = 5\n")
    assert err.value.key == "field.size_x" and "field.blocks_x" in str(err.value)
    with pytest.raises(ParameterError) as err:
        schema.loads_toml("[field]\nsize_x = -3\n")
    assert err.value.key == "field.size_x" and "0.01 to 16384 m" in str(err.value)
    # flags
    parser = argparse.ArgumentParser()
    schema.add_cli_arguments(parser)
    args = parser.parse_args(["--field-size-x", "12.8", "--field-density", "300", "--blade-stiffness", "1"])
    q = schema.defaults().replace(schema.cli_overrides(args))
    assert (q.field.blocks_x, q.field.blades_per_cell, q.blade.root_stiffness) == (8, 3, high)


@pytest.mark.parametrize("file, flags, speed", [
    ({"speed": 3.0}, {"wind.type": "moderate_breeze"}, 6.7),  # another type: its preset speed
    ({"type": "moderate_breeze", "speed": 3.0}, {"wind.type": "moderate_breeze"}, 3.0),  # the same: nothing changes
    ({"type": "moderate_breeze", "speed": 3.0}, {"wind.speed": 1.0, "wind.type": "calm"}, 1.0),  # a speed given wins
])
def test_flags_put_into_a_scene_file_keep_the_wind_types_rules(file, flags, speed):
    """Flags go into the scene file's text before it is read (issue #37 item 9); a flag's wind type
    still brings its preset speed unless the flags give one, as on top of a read file."""
    assert schema.from_dict(schema.merge_flags({"wind": file}, flags)).wind.speed == speed


def test_the_typed_sections_are_the_schemas():
    """params_typed.py, the types mypy checks the reads of parameters with, is the schema's as it is
    now (``python3.11 dev.py params`` writes it again): a section class per section, an attribute
    per parameter, a TypedDict per table's rows."""
    from pathlib import Path

    written = (Path(schema.__file__).with_name("params_typed.py")).read_text()
    assert written == schema.typed_source(), "run python3.11 dev.py params"
    assert "    speed: float\n" in written and "class BladeSpeciesRow(TypedDict):" in written
    assert written.count("Section(Section):") == len(schema.SECTIONS)
