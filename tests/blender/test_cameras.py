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


def test_the_fields_edge_seen_from_outside_comes_down_to_the_ground(runtime):
    """Add Grass Field's meadow thins out over its edge (0.8 m): the far canopy's plane and the
    fringe along the boundary come down with it, so from outside (the elevated viewport, a drone)
    the edge reads as grass thinning out, not a wall: on the boundary the canopy and its fringe stand
    at most 15 % of the tallest stem (the blades there: 12 % of their length), the plane a quarter
    of its height inside or less; in Solid shading the cards are drawn see-through (overlapping into
    a grassy layer, not shards)."""
    from windgrass.grass_addon.bridge import owned

    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    item = bpy.context.scene.windgrass.fields[0]
    assert item.field.edge > 0.5
    ground = owned.ground_object(item).evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = ground.data
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    floor = {i for p in mesh.polygons if p.material_index == 0 for i in p.vertices}
    canopy = sorted({i for p in mesh.polygons if p.material_index == 1 for i in p.vertices} - floor)
    top = co[canopy]
    half = 0.5 * np.array([item.field.blocks_x, item.field.blocks_y]) * item.field.cells_per_block \
        * item.field.cell_size
    boundary = np.abs(np.abs(top[:, :2]) - half).min(axis=1) < 1e-3
    inside = (np.abs(top[:, :2]).max(axis=1) < half.min() - item.field.edge + 1e-3) & ~boundary
    assert inside.any() and boundary.sum() >= 4
    tallest = max(row.length + 4.0 * row.length_variation for row in item.blade.species)
    assert top[boundary, 2].max() <= 0.15 * tallest, (top[boundary, 2].max(), tallest)  # (blades there: 12 %)
    assert top[inside, 2].min() > 4.0 * top[boundary, 2].min()  # (the canopy's plane comes down)
    cards = owned.registered(item)[owned.ROLE_CARD_MATERIAL]
    assert cards.diffuse_color[3] < 0.6
