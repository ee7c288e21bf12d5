"""Terrain: Add > Grass Field on Selected Mesh roots the blades on the mesh's surface.

Small fields (2 x 2 blocks of 8 x 8 cells of 0.1 m, 1.6 m square) on a 4 m grid mesh keep this fast.
"""

from __future__ import annotations

import bpy
import numpy as np
import pytest

SLOPE = 0.2  # terrain z = SLOPE * x + LIFT in the mesh's frame (11 degrees)
LIFT = 0.5
OFFSET = (3.0, 1.0, 0.0)  # where the terrain object stands


@pytest.fixture
def bridge(with_bridge):
    from windgrass.grass_addon.bridge import owned, runtime

    return owned, runtime


def _slope_mesh(func=lambda co: SLOPE * co[:, 0] + LIFT, location=OFFSET, quads=20):
    """A 4 m grid of ``quads`` x ``quads`` displaced to z = func(local xy), selected and active."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=quads, y_subdivisions=quads, size=4.0, location=location)
    obj = bpy.context.active_object
    _displace(obj, func)
    return obj


def _displace(obj, func):
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    co[:, 2] = func(co)
    mesh.vertices.foreach_set("co", co.ravel())
    mesh.update()


def _add_field(**options):
    values = {"blocks_x": 2, "blocks_y": 2, "cells_per_block": 8, "use_selected_mesh": True,
              "edge": 0.0}  # (a field of 1.6 m: no thinning edge, which would lower its canopy everywhere)
    values.update(options)
    assert bpy.ops.windgrass.field_add(**values) == {"FINISHED"}
    scene = bpy.context.scene
    return scene, scene.windgrass.fields[-1]


def _positions(obj) -> np.ndarray:
    out = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.attributes["position"].data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def _blade_joints_world(scene, item, runtime) -> np.ndarray:
    """(blades, n + 1, 2, 3) world-space vertices of every blade slot that shows a block."""
    rt = runtime.get_runtime(scene, item)
    n = rt.field.layout.segments
    slots = {o["wg_slot"]: o for o in item.collection.objects if o.get("wg_role") == "blades"}

    k = rt.blades.shape.k  # blocks per slot object
    out = []
    for position in np.flatnonzero(rt.blades.state.shown >= 0):
        obj = slots[int(position) // k]
        m = np.array(obj.matrix_world)
        local = _positions(obj).reshape(k, -1, 3)[int(position) % k]
        out.append((local @ m[:3, :3].T + m[:3, 3]).reshape(-1, n + 1, 2, 3))
    assert out, "no blade slot shows a block"
    return np.concatenate(out)


def test_blades_are_rooted_on_the_selected_mesh(bridge):
    owned, runtime = bridge
    from windgrass.grass_addon.bridge import meshes
    terrain = _slope_mesh()
    scene, item = _add_field()
    assert item.terrain == terrain
    # The field is centred on the terrain (its XY bounding-box centre).
    ground = owned.ground_object(item)
    assert tuple(ground.matrix_world.translation)[:2] == pytest.approx(OFFSET[:2], abs=1e-6)
    scene.frame_set(1)
    before = _blade_joints_world(scene, item, runtime)
    assert len(before) == 2 * 2 * 8 * 8 * 2  # every blade of the 4 blocks is drawn (no camera)
    # Every root (centre of joint 0) lies on the terrain surface z = 0.2 (x - 3) + 0.5, within 1 mm.
    root = before[:, 0].mean(axis=1)
    surface = SLOPE * (root[:, 0] - OFFSET[0]) + LIFT
    assert np.abs(root[:, 2] - surface).max() < 1e-3
    assert root[:, 2].max() - root[:, 2].min() > 0.25  # a real slope: 1.6 m across at 0.2
    # Frames still sway the tips, and the roots stay planted.
    scene.frame_set(30)
    after = _blade_joints_world(scene, item, runtime)
    assert np.linalg.norm(after[:, -1] - before[:, -1], axis=-1).max() > 1e-3
    np.testing.assert_allclose(after[:, 0].mean(axis=1), root, atol=1e-5)
    # Tips stand above their roots on the slope (grass grows up, along gravity).
    assert np.median(after[:, -1].mean(axis=1)[:, 2] - after[:, 0].mean(axis=1)[:, 2]) > 0.05
    # The ground grid follows the surface (a hair above it, against z-fighting).
    g = np.array(ground.matrix_world)
    gv = _positions(ground) @ g[:3, :3].T + g[:3, 3]
    # vertices: the ground's layer, the far canopy's (the same grid, higher up), its fringe's top
    layer = len({i for p in ground.data.polygons if p.material_index == 0 for i in p.vertices})
    floor, canopy = gv[:layer], gv[layer:2 * layer]
    assert len(floor) > 4
    np.testing.assert_allclose(floor[:, 2], SLOPE * (floor[:, 0] - OFFSET[0]) + LIFT + meshes.GROUND_LIFT,
                               atol=1e-4)
    lift = canopy[:, 2] - floor[:, 2]
    assert lift.min() > 0.05 and np.ptp(lift) < 1e-4
    assert ground.active_material is not None and ground.active_material.get("wg_role") == "ground_material"


def test_a_bumpy_terrain_does_not_show_through_the_field(bridge):
    """Issue #37 item 2: a field on a rough mesh showed the terrain's material through the grass as
    dashed lines along its grid (its ridges rose above the ground drawn 2 mm over a smooth sampling
    of it). Rays straight down over the field, 40 x 40 of them, first meet the grass or the field's
    ground, never the terrain, while the ground still follows it (within a few centimetres)."""
    owned, _ = bridge
    terrain = _slope_mesh(lambda co: 0.3 * np.sin(3.1 * co[:, 0]) * np.cos(2.3 * co[:, 1]) + 0.15 * np.sin(
        11.0 * co[:, 0] + 7.0 * co[:, 1]) + LIFT, location=(3.07, 1.13, 0.0), quads=7)
    scene, item = _add_field()
    scene.frame_set(1)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    x, y = np.meshgrid(np.linspace(-0.78, 0.78, 40), np.linspace(-0.78, 0.78, 40))
    first = []
    centre = np.array(terrain.location)[:2]  # (the field is centred on its terrain)
    ground = owned.ground_object(item)
    canopy = {p.index for p in ground.data.polygons if p.material_index != 0}
    for px, py in zip(x.ravel() + centre[0], y.ravel() + centre[1]):
        z = 5.0
        while True:  # (through the far canopy's layer: a see-through plane where the blades are drawn)
            hit, location, _, face, obj, _ = scene.ray_cast(depsgraph, (px, py, z), (0.0, 0.0, -1.0))
            assert hit
            if obj.name != ground.name or face not in canopy:
                break
            z = location.z - 1e-4
        first.append((obj.name, location.z))
    shown = [name for name, _ in first if name == terrain.name]
    assert not shown, f"{len(shown)} of {len(first)} rays from above meet the terrain first"
    assert {name for name, _ in first} <= {o.name for o in item.collection.all_objects}
    g = np.array(ground.matrix_world)
    floor = _positions(ground) @ g[:3, :3].T + g[:3, 3]
    inside = np.all(np.abs(floor[:, :2] - centre) < 0.75, axis=1)
    # (the ground's floor layer: below everything else of the field at its place)
    co = _positions(terrain) @ np.array(terrain.matrix_world)[:3, :3].T + np.array(terrain.matrix_world)[:3, 3]
    near = np.all(np.abs(co[:, :2] - centre) < 0.7, axis=1)
    assert inside.any() and near.any()
    assert floor[inside, 2].min() < co[near, 2].max()  # (it follows the bumps: not a lid above them)


def test_field_size_fits_the_terrain_unless_given(bridge):
    from windgrass.grass_addon.bridge import properties

    _slope_mesh()
    scene, item = _add_field(blocks_x=1, blocks_y=1)
    assert properties.params_from_settings(item).field.blocks_x == 1  # given: kept
    bpy.ops.object.select_all(action="DESELECT")
    terrain = bpy.data.objects["Grid"]
    terrain.select_set(True)
    bpy.context.view_layer.objects.active = terrain
    assert bpy.ops.windgrass.field_add(cells_per_block=8, use_selected_mesh=True) == {"FINISHED"}
    f = properties.params_from_settings(scene.windgrass.fields[-1]).field
    assert (f.blocks_x, f.blocks_y) == (5, 5)  # 4 m / 0.8 m blocks


def test_modifiers_of_the_terrain_count(bridge):
    """The evaluated mesh is sampled: a Displace modifier (no texture: strength * (1 - midlevel)
    along the normal) lifts a flat plane to z = 0.25, and so the roots."""

    owned, runtime = bridge
    terrain = _slope_mesh(func=lambda co: np.zeros(len(co)), location=(0.0, 0.0, 0.0))
    mod = terrain.modifiers.new("Lift", "DISPLACE")
    mod.strength = 0.5
    scene, item = _add_field()
    scene.frame_set(2)
    root = _blade_joints_world(scene, item, runtime)[:, 0].mean(axis=1)
    np.testing.assert_allclose(root[:, 2], 0.25, atol=1e-4)


def test_rebuild_resamples_an_edited_terrain_and_reopen_resamples(bridge, tmp_path):
    owned, runtime = bridge
    terrain = _slope_mesh()
    scene, item = _add_field()
    scene.frame_set(3)
    digest = runtime.get_runtime(scene, item).digest
    _displace(terrain, lambda co: -SLOPE * co[:, 1])  # now tilted along -Y, no lift
    scene.frame_set(4)
    assert runtime.get_runtime(scene, item).digest == digest  # no re-sampling per frame
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    assert runtime.get_runtime(scene, item).digest != digest
    scene.frame_set(5)
    root = _blade_joints_world(scene, item, runtime)[:, 0].mean(axis=1)
    assert np.abs(root[:, 2] + SLOPE * (root[:, 1] - OFFSET[1])).max() < 1e-3
    expected = _blade_joints_world(scene, item, runtime)
    # Save and reopen: the runtime is rebuilt from item.terrain and gives the same blades.
    before = runtime.get_runtime(scene, item).field
    path = tmp_path / "terrain.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert all(rt.field is not before for rt in runtime.REGISTRY.fields.values())
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(2)
    scene.frame_set(5)
    assert item.terrain is not None and runtime.get_runtime(scene, item).heightfield is not None
    np.testing.assert_allclose(_blade_joints_world(scene, item, runtime), expected, atol=1e-6)


def test_removing_the_field_keeps_the_terrain_and_a_deleted_terrain_waits_for_rebuild(bridge, capsys):
    owned, runtime = bridge
    terrain = _slope_mesh()
    mesh_name, verts = terrain.data.name, len(terrain.data.vertices)
    scene, item = _add_field()
    assert bpy.ops.windgrass.field_remove() == {"FINISHED"}
    assert bpy.data.objects.get("Grid") is terrain and terrain.name in scene.objects
    assert bpy.data.meshes.get(mesh_name) is not None and len(terrain.data.vertices) == verts

    # A field whose terrain is deleted keeps the ground it was built on (one warning, no exception,
    # no objects rebuilt by a frame handler); Rebuild puts it on flat ground.
    terrain.select_set(True)
    bpy.context.view_layer.objects.active = terrain
    scene, item = _add_field()
    scene.frame_set(2)
    capsys.readouterr()
    bpy.data.objects.remove(terrain, do_unlink=True)
    scene.frame_set(3)
    scene.frame_set(4)
    out = capsys.readouterr().out
    assert out.count("terrain of field 'Grass'") == 1 and "until Rebuild" in out
    assert runtime.get_runtime(scene, item).heightfield is not None
    assert runtime.field_error(scene, item) is None
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    out = capsys.readouterr().out
    assert "terrain 'Grid'" in out and "flat ground" in out
    rt = runtime.get_runtime(scene, item)
    assert rt.heightfield is None
    ground = owned.ground_object(item)
    assert tuple(ground.matrix_world.translation)[:2] == pytest.approx(OFFSET[:2], abs=1e-6)  # stays put
    root = _blade_joints_world(scene, item, runtime)[:, 0].mean(axis=1)
    np.testing.assert_allclose(root[:, 2], 0.0, atol=1e-6)


@pytest.mark.parametrize("size", [30.0, 300.0])
def test_grass_field_on_selected_mesh_covers_the_mesh_or_says_how_much(bridge, capfd, size):
    """Issue #63 item 1: on a 30 m plane with a Displace modifier the field covered 25.6 m (256
    blocks of 1.6 m at most) and a 2.2 m rim stayed bare, white in renders, with no message. The
    ground the field draws now reaches the mesh's edges (its blocks grow past 256 of them); a mesh
    larger than the largest blocks can cover is covered as far as they reach, and the report says
    how much, and how to cover the rest."""
    owned, runtime = bridge
    bpy.ops.mesh.primitive_plane_add(size=size)
    plane = bpy.context.active_object
    plane.modifiers.new("Lift", "DISPLACE").strength = 0.2
    assert bpy.ops.windgrass.field_add(use_selected_mesh=True) == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[-1]
    scene.frame_set(1)
    ground = owned.ground_object(item)
    corners = np.array([ground.matrix_world @ v.co for v in ground.evaluated_get(
        bpy.context.evaluated_depsgraph_get()).data.vertices])[:, :2]
    reach = np.abs(corners).max(axis=0)
    assert runtime.field_error(scene, item) is None
    said = capfd.readouterr()
    if size == 30.0:
        assert np.all(reach >= size / 2 - 1e-3) and np.all(reach < size / 2 + 1.0), reach  # the whole mesh
        assert "covers" not in said.out + said.err
    else:
        assert np.all(reach < size / 2)  # (as far as 256 of the largest blocks reach)
        assert f"of the {size:.4g} x {size:.4g} m mesh" in said.out + said.err and "Size X/Y" in said.out + said.err
