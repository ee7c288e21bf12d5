"""A wind that loops, in Blender: the meshes Blender draws, and the pixels it renders, at frame k
and one loop later are the same; the panel says what breaks a loop (a keyed wind)."""

from __future__ import annotations

import numpy as np


def _loop_params(**more):
    from windgrass.grass_addon import schema

    values = {"field.blocks_x": 6, "field.blocks_y": 6, "simulation.preroll": 1.0, "simulation.epoch": 1.0,
              "simulation.loop": 2.0, "wind.speed": 5.0, "wind.gust_waves": 0.6, "camera.mode": "fixed",
              "camera.position": (0.0, -4.0, 1.1), "camera.target": (0.0, 3.0, 0.0), "render.engine": "cycles",
              "render.samples": 2, "render.resolution_x": 96, "render.resolution_y": 54, "render.frame_end": 120}
    values.update(more)
    return schema.defaults().replace(values)


def test_blender_draws_and_renders_the_same_frame_one_loop_later(rendered, drawn, tmp_path):
    import bpy

    params = _loop_params()
    period = 48  # 2 s at 24 fps
    first = rendered(params, 7, tmp_path / "a.png")
    item = bpy.context.scene.windgrass.fields[0]
    blades, cards = drawn(item, "blades"), drawn(item, "cards")
    assert len(blades) and np.any(blades)
    later = rendered(params, 7 + period, tmp_path / "b.png")
    item = bpy.context.scene.windgrass.fields[0]
    np.testing.assert_array_equal(drawn(item, "blades"), blades)
    np.testing.assert_array_equal(drawn(item, "cards"), cards)
    np.testing.assert_array_equal(later, first)
    bpy.context.scene.frame_set(8)
    assert not np.array_equal(drawn(item, "blades"), blades), "the grass stood still"


def test_the_panel_says_a_keyed_wind_breaks_the_loop(with_bridge):
    import bpy
    from windgrass.grass_addon.bridge import properties, runtime

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    keyed = _loop_params(**{"wind.keys": ({"time": 0.0, "speed": 3.0, "direction": 0.0},
                                          {"time": 1.5, "speed": 6.0, "direction": 10.0})})
    item = properties.add_field(scene, keyed)
    runtime.build_field(scene, item)
    notes = runtime.loop_notes(scene, item)
    assert len(notes) == 1 and "keyed" in notes[0]
    item.simulation.loop = 0.0
    assert runtime.loop_notes(scene, item) == []
