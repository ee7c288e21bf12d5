"""Inside Blender the scene's frame rate and frame range are the only clock of a field."""

import bpy
import numpy as np
import pytest


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
    assert sim.fps == 30 and sim.frame_start == 5  # frames per second and the first frame
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


@pytest.mark.parametrize("fps", [30, 24])
def test_a_fractional_frame_rate_times_the_wind_as_blender_times_its_frames(runtime, drawn, fps):
    """At 29.97 and 23.976 fps (fps_base 1.001) a wind that rises at T seconds first moves the
    grass on the frame Blender's own clock (``bpy.utils.time_from_frame``) puts after T: 3,000
    frames in, read at the whole rate the grass would still stand three frames later."""
    assert bpy.ops.windgrass.field_add(blocks_x=1, blocks_y=1, cells_per_block=4) == {"FINISHED"}
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = fps, 1.001
    scene.frame_start, scene.frame_end = 1, 4000
    item = scene.windgrass.fields[0]
    item.wind.turbulence, item.wind.gust_waves = 0.0, 0.0
    rise = (3000 + 0.5) * 1.001 / fps  # half a frame after frame 3001 at the scene's rate
    for time, speed in ((0.0, 0.0), (rise, 0.0), (rise + 0.01, 12.0)):
        assert bpy.ops.windgrass.row_add(table="wind.keys") == {"FINISHED"}
        key = item.wind.keys[-1]
        key.time, key.speed, key.direction = time, speed, 0.0

    def seconds(frame):
        return bpy.utils.time_from_frame(frame - scene.frame_start).total_seconds()

    first = next(f for f in range(2990, 3020) if seconds(f) > rise)
    assert first == 3002  # Blender's clock: frame 3002 is 3001 * 1.001 / fps s in
    poses = {}
    for frame in (first - 3, first - 1, first + 2):
        scene.frame_set(frame)
        assert runtime.field_error(scene, item) is None
        poses[frame] = drawn(item)
    still = np.abs(poses[first - 1] - poses[first - 3]).max()
    moved = np.abs(poses[first + 2] - poses[first - 1]).max()
    assert still < 1e-5, f"the grass moved {still:.2e} m before the wind rose"
    assert moved > 1e-3, f"the grass moved only {moved:.2e} m two frames after the wind rose"
