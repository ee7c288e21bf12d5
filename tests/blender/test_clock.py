"""Inside Blender the scene's frame rate and frame range are the only clock of a field."""

import bpy
import pytest


@pytest.fixture
def runtime(with_bridge):
    from windgrass.grass_addon.bridge import runtime

    return runtime


def test_the_scene_clock_rules_over_the_fields_render_settings(runtime):
    assert bpy.ops.windgrass.field_add(blocks_x=1, blocks_y=1, cells_per_block=4) == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    item.render.fps = 12  # the field's own setting (headless renders): not Blender's clock
    item.render.frame_start = 40
    scene.render.fps = 30
    scene.frame_start, scene.frame_end = 5, 80
    scene.frame_set(20)
    sim = runtime.get_runtime(scene, item).field.sim
    assert sim.fps == 30 and sim.frame_start == 5
    assert sim.time(20) == pytest.approx(15 / 30)
    scene.render.fps = 60  # the scene changes: the field follows
    scene.frame_set(21)
    sim = runtime.get_runtime(scene, item).field.sim
    assert sim.fps == 60 and sim.time(21) == pytest.approx(16 / 60)


def test_a_scene_rate_out_of_range_is_named_as_the_scenes(runtime):
    assert bpy.ops.windgrass.field_add(blocks_x=1, blocks_y=1, cells_per_block=4) == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.render.fps = 500
    scene.frame_set(3)
    error = runtime.field_error(scene, item)
    assert error and "render.fps" in error and "scene's" in error and "1 to 240" in error
