"""The extension shell: package build/validate/install, registration, generated properties,
settings <-> Params, operators and presets (scene building and renders are tested elsewhere)."""

import json
import math
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import bpy
import pytest

REPO = Path(__file__).resolve().parents[2]
OPERATORS = ("field_add", "field_rebuild", "field_remove", "simulation_reset", "wind_preset",
             "species_preset", "row_add", "row_remove", "field_bake", "field_bake_free", "map_pick",
             "track_update", "farm_job", "field_duplicate", "wind_force_add", "field_map_add")


def _blender_ext() -> Path:
    return Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"


def _run(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    """The extension zip built by Blender's own tool, with the tags checked against Blender's list."""
    from _bpy_internal.extensions import tags

    out = tmp_path_factory.mktemp("ext")
    valid_tags = out / "tags.json"
    valid_tags.write_text(json.dumps({"add-on": sorted(tags.addons), "theme": sorted(tags.themes)}))
    result = _run(str(_blender_ext()), "build", "--source-dir", str(REPO), "--output-dir", str(out),
                  f"--valid-tags={valid_tags}")
    assert result.returncode == 0, result.stdout + result.stderr
    zips = list(out.glob("windgrass-*.zip"))
    assert len(zips) == 1, result.stdout
    return zips[0]


# --------------------------------------------------------------------------------------------
# Package


def test_manifest_validates_in_place():
    import tomllib

    result = _run(str(_blender_ext()), "validate", str(REPO))
    assert result.returncode == 0, result.stdout + result.stderr
    manifest = tomllib.loads((REPO / "blender_manifest.toml").read_text())
    assert "files" in manifest["permissions"]  # the bake writes caches beside the .blend


def test_built_zip_validates_and_holds_only_the_extension(package):
    result = _run(str(_blender_ext()), "validate", str(package))
    assert result.returncode == 0, result.stdout + result.stderr
    names = zipfile.ZipFile(package).namelist()
    for needed in ("blender_manifest.toml", "__init__.py", "grass_addon/schema.py",
                   "grass_addon/bridge/properties.py", "operators/field_add.py", "panels/sections.py"):
        assert needed in names
    for name in names:
        top = name.split("/", 1)[0]
        assert top not in ("headless", "tests", "docs", ".git", ".ci", ".venv", "renders"), name
        assert "__pycache__" not in name and not name.endswith((".pyc", ".zip")), name
        assert name not in ("dev.py", "requirements.txt", "ruff.toml", "DEVELOPERS.md"), name


INSTALL_SCRIPT = textwrap.dedent("""
    import json
    import sys

    import bpy
    import addon_utils
    zip_path, out = sys.argv[-2:]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    module = sys.modules["bl_ext.user_default.windgrass"]
    frame_handlers = lambda: [h.__module__ for h in bpy.app.handlers.frame_change_pre]
    report = {
        "file": module.__file__,
        "registered": module._registered,
        "scene_prop": hasattr(bpy.types.Scene, "windgrass"),
        "ops": [op for op in dir(bpy.ops.windgrass)],
        "handlers": frame_handlers(),
    }
    addon_utils.disable("bl_ext.user_default.windgrass", default_set=True)
    report["after_disable"] = {
        "scene_prop": hasattr(bpy.types.Scene, "windgrass"),
        "ops": [op for op in dir(bpy.ops.windgrass)],
        "handlers": frame_handlers(),
    }
    open(out, "w").write(json.dumps(report))
""")


def test_zip_installs_into_a_user_repository_and_enables(package, tmp_path):
    """Install from Disk into a fresh user repository: imports as bl_ext.user_default.windgrass."""
    script = tmp_path / "install.py"
    script.write_text(INSTALL_SCRIPT)
    out = tmp_path / "report.json"
    user = tmp_path / "user"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user), HOME=str(tmp_path))
    result = _run(str(script), str(package), str(out), env=env)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads(out.read_text())
    installed = user / "extensions" / "user_default" / "windgrass"
    assert Path(report["file"]).resolve() == (installed / "__init__.py").resolve()
    assert report["registered"] and report["scene_prop"]
    assert set(OPERATORS) <= set(report["ops"])
    after = report["after_disable"]
    assert not after["scene_prop"] and not after["ops"]
    assert not [m for m in after["handlers"] if "windgrass" in m]


# --------------------------------------------------------------------------------------------
# Registration


def test_operators_are_registered_and_searchable():
    for name in OPERATORS:
        assert name in dir(bpy.ops.windgrass)
        rna = getattr(bpy.ops.windgrass, name).get_rna_type()
        assert rna.name and rna.description, name  # F3 finds them by label and description
    assert bpy.ops.windgrass.field_add.get_rna_type().name == "Add Grass Field"
    from windgrass import operators

    assert sorted(cls.bl_idname for cls in operators.CLASSES) == sorted(f"windgrass.{n}" for n in OPERATORS)
    for cls in operators.CLASSES:
        assert cls.bl_options >= {"REGISTER", "UNDO"}, cls.bl_idname


def test_add_menu_has_the_grass_field_entry(addon):
    from windgrass.operators import field_add

    draw_funcs = bpy.types.VIEW3D_MT_add._dyn_ui_initialize()
    assert draw_funcs.count(field_add.menu_func) == 1


def test_unregister_removes_everything_and_register_is_idempotent(addon):
    from windgrass.operators import field_add

    addon.register()  # second call: nothing registered twice
    assert bpy.types.VIEW3D_MT_add._dyn_ui_initialize().count(field_add.menu_func) == 1
    addon.unregister()
    addon.unregister()
    try:
        assert not hasattr(bpy.types.Scene, "windgrass")
        assert not dir(bpy.ops.windgrass)
        assert field_add.menu_func not in bpy.types.VIEW3D_MT_add._dyn_ui_initialize()
        assert not [h for h in bpy.app.handlers.frame_change_pre if h.__module__.startswith("windgrass")]
        assert not hasattr(bpy.types, "WINDGRASS_PT_main")
    finally:
        addon.register()
    assert hasattr(bpy.types.Scene, "windgrass")


def test_every_section_has_a_sidebar_panel(addon):
    from windgrass.grass_addon import schema

    batch_only = {"camera", "render", "terrain"}  # (in the closed Batch Renders panel: issue #63)
    for section in schema.SECTIONS:
        panel = getattr(bpy.types, f"WINDGRASS_PT_{section}")
        parent = "WINDGRASS_PT_batch" if section in batch_only else "WINDGRASS_PT_main"
        assert panel.bl_category == "Grass" and panel.bl_parent_id == parent


def test_type_specific_wind_and_camera_parameters_follow_their_mode(addon):
    """Gust parameters are shown for a blast, vortex ones for a whirlwind (schema applies_when)."""
    from windgrass.grass_addon import schema

    def condition(name):
        return schema.BY_NAME[name].applies_when or None

    assert condition("wind.gust_speed") == ("type", "blast")
    assert condition("wind.vortex_radius") == ("type", "whirlwind")
    assert condition("wind.speed") is None
    assert condition("camera.position") == ("mode", "fixed")
    assert condition("camera.speed") == ("mode", "flythrough")


# --------------------------------------------------------------------------------------------
# Generated properties


def _schema():
    from windgrass.grass_addon import schema

    return schema


def _check_property(p, rna):
    """The RNA property of schema parameter ``p`` has its help, hard range and default."""
    assert p.help in rna.description, p.name
    scale = math.radians(1.0) if p.unit == "deg" else 1.0  # angles live in radians in Blender
    if p.kind in ("int", "float", "vec"):
        assert rna.hard_min == pytest.approx(p.minimum * scale, rel=1e-6), p.name
        assert rna.hard_max == pytest.approx(p.maximum * scale, rel=1e-6), p.name
    if p.kind == "float":
        assert rna.default == pytest.approx(p.default * scale, rel=1e-6), p.name
    elif p.kind == "vec":
        assert tuple(rna.default_array) == pytest.approx([v * scale for v in p.default], rel=1e-6), p.name
    elif p.kind == "enum":
        assert rna.default == p.default and tuple(rna.enum_items.keys()) == p.choices, p.name
    else:
        assert rna.default == p.default, p.name


def test_every_parameter_has_a_property_with_the_schema_default_and_hard_range(scene):
    from windgrass.grass_addon.bridge import properties

    schema = _schema()
    item = properties.add_field(scene)
    for p in schema.PARAMS:
        if not p.blender:  # scene files only ([[colliders]]): Blender's collections give them
            assert p.key not in properties.group(item, p.section).bl_rna.properties, p.name
            continue
        rna = properties.group(item, p.section).bl_rna.properties[p.key]
        if p.kind != "table_list":
            _check_property(p, rna)
            continue
        assert rna.type == "COLLECTION"
        row_rna = properties.ROW_CLASSES[p.name].bl_rna
        for f in p.fields:
            # a "name" column overrides PropertyGroup.name: RNA lists both, the override last
            _check_property(f, [q for q in row_rna.properties if q.identifier == f.key][-1])


def test_units_map_to_blender_subtypes(scene):
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    props = item.wind.bl_rna.properties
    assert props["direction"].subtype == "ANGLE"
    assert props["speed"].unit == "VELOCITY"
    assert props["turbulence_scale"].subtype == "DISTANCE"
    assert props["turbulence_period"].unit in ("TIME", "TIME_ABSOLUTE")
    assert props["type"].type == "ENUM"
    assert set(props["type"].enum_items.keys()) == set(_schema().WIND_TYPES)
    assert item.lod.bl_rna.properties["enabled"].type == "BOOLEAN"
    # (its switch is in the Levels of Detail panel's header, as Blender's own Motion Blur's: #37 item 7)
    assert "draw_header" in vars(bpy.types.WINDGRASS_PT_lod)
    species = properties.ROW_CLASSES["blade.species"].bl_rna.properties
    assert species["color"].subtype == "COLOR" and species["color"].array_length == 3
    assert item.camera.bl_rna.properties["position"].array_length == 3


def test_labels_units_and_tooltips_follow_blenders_conventions(scene):
    """Issue: "Blocks X/Y", "Cache (MB)", "Substeps"; a unit on every value that has one (shown
    by Blender's unit system or in the label); tooltips in an artist's words first, the paper's
    symbol after."""
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    names = {f"{p.section}.{p.key}": properties.group(item, p.section).bl_rna.properties[p.key]
             for p in _schema().PARAMS if p.blender}
    assert names["field.blocks_x"].name == "Blocks X" and names["field.blocks_y"].name == "Blocks Y"
    assert names["simulation.sub_steps"].name == "Substeps"
    # units Blender cannot show are written after the value (the labels stay short for the sidebar)
    by_name = _schema().BY_NAME
    assert names["simulation.cache_mb"].name == "Cache"
    assert properties.unit_suffix(by_name["simulation.cache_mb"]) == "MB"
    assert names["blade.density"].name == "Mass/Length" and properties.unit_suffix(by_name["blade.density"]) == "kg/m"
    assert properties.unit_suffix(by_name["blade.damping_mass"]) == "1/s"
    assert properties.unit_suffix(by_name["lod.card_width"]) == "cells"
    assert names["blade.tip_width"].subtype == "FACTOR" and names["lod.card_height"].subtype == "FACTOR"
    symbols = ("mu_root", "d_g1", "d_g2", "d_s1", "d_s2", "alpha", "beta", "gamma", "lambda", "k of", "rho")
    for name, rna in names.items():
        words = rna.name.split()
        assert all(w[:1].isupper() or w in ("per", "of", "\u00d7") for w in words), \
            f"{name}: {rna.name!r} is not in Title Case"
        p = by_name[name]
        if p.unit and p.kind in ("float", "int"):  # Blender shows it, or the panel after the value
            assert rna.subtype in ("DISTANCE", "ANGLE", "TIME_ABSOLUTE", "PIXEL", "FACTOR") or rna.unit != "NONE" \
                or properties.unit_suffix(p), f"{name}: no unit shown"
        first = rna.description.split()[0].lower()
        assert not any(first.startswith(s) for s in symbols), f"{name}: tooltip starts with a symbol"


def test_only_wind_speed_and_direction_are_animatable(scene):
    """The runtime samples F-curves of the mean wind; keyframes anywhere else would do nothing."""
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    assert item.wind.bl_rna.properties["speed"].is_animatable
    assert item.wind.bl_rna.properties["direction"].is_animatable
    assert not item.field.bl_rna.properties["blocks_x"].is_animatable
    item.wind.keyframe_insert("speed", frame=1)
    assert scene.animation_data is not None


def test_angles_are_radians_in_blender_and_degrees_in_params(scene):
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    item.wind.direction = math.pi / 2  # an artist types 90 deg in the UI
    assert properties.params_from_settings(item).wind.direction == 90.0


def test_new_field_reads_back_as_the_schema_defaults(scene):
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    assert properties.params_from_settings(item) == _schema().defaults()
    assert item.uid and item.name == "Grass"
    second = properties.add_field(scene)
    assert second.uid != item.uid and second.name == "Grass.001"
    assert scene.windgrass.active_index == 1 and properties.active_field(scene).uid == second.uid
    # uids tag data-blocks shared by all scenes of the file: unique across scenes too
    other = bpy.data.scenes.new("Other")
    assert properties.add_field(other).uid not in (item.uid, second.uid)


def test_params_round_trip_through_the_settings(scene):
    from windgrass.grass_addon import presets
    from windgrass.grass_addon.bridge import properties

    schema = _schema()
    params = presets.apply_preset(schema.defaults(), "meadow").replace({
        "wind.direction": -135.5, "wind.type": "whirlwind", "wind.speed": 2.0, "blade.inclination": 33.3,
        "blade.root_stiffness": 1.7e-4, "field.seed": 123456789, "lod.enabled": False,
        "camera.mode": "fixed", "camera.position": [1.5, -2.25, 3.0], "render.sun_azimuth": -200.0,
        "wind.keys": [{"time": 0.0, "speed": 1.0, "direction": 10.0},
                      {"time": 2.5, "speed": 7.5, "direction": 370.0}],
    })
    item = properties.add_field(scene)
    properties.apply_params(item, params)
    assert properties.params_from_settings(item) == params
    assert len(item.blade.species) == 6 and item.blade.species[1].name == "timothy"


@pytest.mark.parametrize("setting, key", [
    (lambda item: setattr(item.lod, "blade_far", 1.0), "lod.blade_far"),  # below blade_near (6 m)
    (lambda item: [setattr(r, "weight", 0.0) for r in item.blade.species], "blade.species"),
    (lambda item: setattr(item.render, "frame_end", 0), "render.frame_end"),
    (lambda item: (setattr(item.field, "blocks_x", 20000), setattr(item.field, "cells_per_block", 64)),
     "field.blocks_x"),  # 20000 blocks of 64 cells: past float32's millimetre range
    (lambda item: setattr(item.simulation, "epoch", 1.0), "simulation.epoch"),  # below the preroll (3 s)
])
def test_bad_settings_raise_parameter_error_naming_the_key(scene, setting, key):
    from windgrass.grass_addon import presets
    from windgrass.grass_addon.bridge import properties
    from windgrass.grass_addon.errors import ParameterError

    item = properties.add_field(scene, presets.apply_preset(_schema().defaults(), "lawn"))
    setting(item)
    with pytest.raises(ParameterError) as info:
        properties.params_from_settings(item)
    assert info.value.key == key
    assert key in str(info.value)


def test_hard_limits_clamp_what_blender_stores(scene):
    """Blender enforces the schema's hard range: 1000 m/s wind is stored as the 60 m/s maximum."""
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    item.wind.speed = 1000.0
    assert properties.params_from_settings(item).wind.speed == _schema().BY_NAME["wind.speed"].maximum


# --------------------------------------------------------------------------------------------
# Operators that need no scene objects


def test_wind_preset_sets_type_and_nominal_speed(scene):
    from windgrass.grass_addon.bridge import properties

    properties.add_field(scene)
    schema = _schema()
    for wind_type in schema.WIND_TYPES:
        assert bpy.ops.windgrass.wind_preset(type=wind_type) == {"FINISHED"}
        params = properties.params_from_settings(properties.active_field(scene))
        assert params.wind.type == wind_type
        assert params.wind.speed == schema.WIND_TYPE_SPEED[wind_type]
        for name, value in schema.wind_preset(wind_type).items():  # turbulence too
            assert params.get(name) == value, name


def test_wind_preset_warns_when_the_speed_is_keyframed(scene, with_bridge, capfd):
    """Keyframes win over a value set by the preset; the artist is told so (a WARNING report)."""
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    item.wind.keyframe_insert("speed", frame=1)
    capfd.readouterr()
    assert bpy.ops.windgrass.wind_preset(type="calm") == {"FINISHED"}
    assert "Warning: Wind speed is keyframed" in capfd.readouterr().out


def test_species_preset_add_and_remove(scene):
    from windgrass.grass_addon import presets
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    assert bpy.ops.windgrass.species_preset(preset="wild") == {"FINISHED"}
    assert properties.params_from_settings(item).blade.species == presets.species_rows("wild")
    item.blade.species_index = 1
    assert bpy.ops.windgrass.row_add() == {"FINISHED"}
    species = properties.params_from_settings(item).blade.species
    assert len(species) == 4 and species[3] == species[1]  # a copy of the selected row
    assert item.blade.species_index == 3
    assert bpy.ops.windgrass.row_remove() == {"FINISHED"}
    assert bpy.ops.windgrass.row_remove() == {"FINISHED"}
    assert [s["name"] for s in properties.params_from_settings(item).blade.species] == ["tall grass", "reed"]


def test_a_species_preset_says_what_of_the_look_it_changed_or_leaves_it(scene, capfd):
    """Issue #63 item 4: a species preset also changed Clumping, Patches and Floor without a word.
    Its report names each setting of the look it changed; With Its Look off, the species alone
    change and every other setting stays."""
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    before = properties.params_from_settings(item)
    assert bpy.ops.windgrass.species_preset(preset="wild", with_look=False) == {"FINISHED"}
    alone = properties.params_from_settings(item)
    assert alone.blade.species != before.blade.species
    assert alone.replace({"blade.species": [dict(r) for r in before.blade.species]}) == before
    assert "its look too" not in capfd.readouterr().out
    assert bpy.ops.windgrass.species_preset(preset="wild") == {"FINISHED"}
    said = capfd.readouterr()
    field = properties.params_from_settings(item).field
    assert (field.clumping, field.patchiness, field.floor) == (0.5, 0.8, "thatch")
    assert "its look too: Clumping 0.5" in said.out + said.err and "Patches 0.8" in said.out + said.err


def test_add_says_when_it_turns_lock_interface_on(scene, capfd, with_bridge):
    """Issue #63 item 4: the add-on switched Render > Lock Interface on without a word (the frame
    handler writes the grass while a frame renders, which needs it). Add's report says so, once:
    the next Add, with the lock already on, does not."""
    scene.render.use_lock_interface = False
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2) == {"FINISHED"}
    first = capfd.readouterr()
    assert scene.render.use_lock_interface
    assert "Lock Interface turned on" in first.out + first.err
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2) == {"FINISHED"}
    again = capfd.readouterr()
    assert "Added grass field" in again.out + again.err and "Lock Interface" not in again.out + again.err


def test_wind_keys_added_by_the_operator_keep_increasing_times(scene):
    from windgrass.grass_addon.bridge import properties

    item = properties.add_field(scene)
    for _ in range(3):
        assert bpy.ops.windgrass.row_add(table="wind.keys") == {"FINISHED"}
    times = [k["time"] for k in properties.params_from_settings(item).wind.keys]
    assert times == [0.0, 1.0, 2.0]


def test_operators_need_an_active_field_and_report_bad_input(scene):
    from windgrass.grass_addon.bridge import properties

    assert not bpy.ops.windgrass.field_rebuild.poll()
    assert not bpy.ops.windgrass.wind_preset.poll()
    properties.add_field(scene)
    with pytest.raises(RuntimeError, match="not a table parameter"):
        bpy.ops.windgrass.row_add(table="wind.speed")
    properties.active_field(scene).lod.card_far = 1.0
    with pytest.raises(RuntimeError, match=r"lod\.card_far"):  # an ERROR report, not a crash
        bpy.ops.windgrass.field_rebuild()


# --------------------------------------------------------------------------------------------
# Operators that build scene objects (need grass_addon/bridge/scene.py and runtime.py)


def test_field_add_builds_a_light_field_and_remove_deletes_it(scene, with_bridge):
    from windgrass.grass_addon.bridge import properties

    before = {kind: set(getattr(bpy.data, kind).keys()) for kind in ("objects", "meshes", "materials",
                                                                     "images", "collections")}
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    item = properties.active_field(scene)
    assert item.collection is not None and len(item.collection.all_objects) > 0
    params = properties.params_from_settings(item)
    assert (params.field.blocks_x, params.field.blocks_y) == (8, 8)  # light first click
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    assert bpy.ops.windgrass.simulation_reset() == {"FINISHED"}
    assert bpy.ops.windgrass.field_remove() == {"FINISHED"}
    assert len(scene.windgrass.fields) == 0
    after = {kind: set(getattr(bpy.data, kind).keys()) for kind in before}
    assert after == before


def test_field_add_with_a_selected_mesh(scene, with_bridge):
    from windgrass.grass_addon.bridge import properties

    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plane = bpy.context.active_object
    # A selected mesh (the startup file's Cube, say) stays a mesh: Add grows on flat ground ...
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2) == {"FINISHED"}
    assert properties.active_field(scene).terrain is None
    # ... unless the artist asks for the mesh ("Grass Field on Selected Mesh").
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=3, use_selected_mesh=True) == {"FINISHED"}
    item = properties.active_field(scene)
    params = properties.params_from_settings(item)
    assert (params.field.blocks_x, params.field.blocks_y) == (2, 3)
    assert item.collection is not None
    assert item.terrain == plane  # the selected mesh became the field's terrain
    # A field's own ground is never a terrain; asking for a mesh with none selected says so.
    ground = next(o for o in item.collection.objects if o.get("wg_role") == "ground")
    bpy.ops.object.select_all(action="DESELECT")
    ground.select_set(True)
    bpy.context.view_layer.objects.active = ground
    fields = len(scene.windgrass.fields)
    with pytest.raises(RuntimeError, match="belongs to a grass field"):
        bpy.ops.windgrass.field_add(use_selected_mesh=True)
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}  # + in the panel: flat ground
    assert properties.active_field(scene).terrain is None
    bpy.ops.object.select_all(action="DESELECT")
    with pytest.raises(RuntimeError, match="select the mesh to grow the grass on first"):
        bpy.ops.windgrass.field_add(use_selected_mesh=True)
    assert len(scene.windgrass.fields) == fields + 1
