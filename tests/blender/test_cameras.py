"""Every camera an artist uses (issue #59): the level of detail by how large a blade is on screen.
Assertions read what Blender draws: the evaluated slot meshes and the far canopy's material."""

import bpy
import numpy as np

EYE_LEVEL = (0.0, 0.0, 1.2), (np.radians(85.0), 0.0, np.radians(-90.0))  # (location, rotation): looking along +X


def _eye(scene, location=EYE_LEVEL[0], rotation=EYE_LEVEL[1]):
    cam = bpy.data.objects.new("eye", bpy.data.cameras.new("eye"))
    scene.collection.objects.link(cam)
    cam.location = location
    cam.rotation_euler = rotation
    cam.data.sensor_fit = "HORIZONTAL"
    cam.data.angle = np.radians(55.0)
    scene.camera = cam
    return cam


def test_a_larger_frame_draws_blades_further_out_and_the_canopy_further_back(runtime, stems):
    """The same camera over a 51 m meadow: rendering 1920 pixels wide instead of 960, a blade is
    as large on screen twice as far away, so Blender draws blades to about twice the distance
    (the stems it draws, read from the evaluated meshes) and the far canopy starts twice as far
    (its eq 10 distances, read from the material); 640 pixels wide draws what 960 does (the
    settings' distances are never shortened)."""
    from windgrass.grass_addon.bridge import materials, owned

    assert bpy.ops.windgrass.field_add(blocks_x=32, blocks_y=32) == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    _eye(scene)
    canopy = owned.registered(item)[owned.ROLE_CANOPY_MATERIAL].node_tree.nodes[materials.NODE_KT]
    reach = {}
    for width in (640, 960, 1920):
        scene.render.resolution_x, scene.render.resolution_y = width, width * 9 // 16
        scene.frame_set(2)
        roots = stems(item)[:, 0].mean(axis=1)
        reach[width] = float(np.percentile(np.hypot(roots[:, 0], roots[:, 1]), 99))
        near = canopy.inputs["From Min"].default_value
        assert abs(near - item.lod.card_near * (2.0 if width == 1920 else 1.0)) < 1e-4, (width, near)
    assert abs(reach[640] - reach[960]) < 0.5 and 1.6 * reach[960] < reach[1920] < 2.2 * reach[960], reach
    item.lod.screen_size = False
    scene.frame_set(3)
    roots = stems(item)[:, 0].mean(axis=1)
    assert float(np.percentile(np.hypot(roots[:, 0], roots[:, 1]), 99)) < 1.2 * reach[960]
