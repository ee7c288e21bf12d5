"""What a field owns and what it answers for: copied scenes, a user's copies of grass objects,
renamed scenes, and settings that cannot be simulated (grass hidden, error shown, render fails)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest


@pytest.fixture
def bridge(with_bridge):
    from windgrass.grass_addon.bridge import owned, runtime

    return owned, runtime


def _add_field():
    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2, cells_per_block=8) == {"FINISHED"}
    scene = bpy.context.scene
    return scene, scene.windgrass.fields[-1]


def _positions(obj) -> np.ndarray:
    out = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.attributes["position"].data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def _grass_objects(scene) -> set[str]:
    return {o.name for o in scene.objects if o.get("wg_role")}


def test_a_full_copy_of_the_scene_is_a_field_of_its_own(bridge):
    owned, runtime = bridge
    original, item = _add_field()
    original_objects = _grass_objects(original)
    bpy.ops.scene.new(type="FULL_COPY")
    copy = bpy.context.scene
    copy_item = copy.windgrass.fields[0]
    copy.frame_set(5)
    assert copy_item.collection is not item.collection
    # Blender's copies of the slots are kept out of files as the originals are (autosaves stay small)
    copies = [o for o in copy_item.collection.objects if o.get("wg_role") in (owned.ROLE_BLADES, owned.ROLE_CARDS)]
    assert copies and all(o.is_runtime_data and o.data.is_runtime_data for o in copies)
    assert runtime.get_runtime(copy, copy_item).field is not runtime.get_runtime(original, item).field
    # Rebuild and Remove in the copy leave the original's grass alone.
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    assert copy_item.collection["wg_uid"] != item.collection["wg_uid"]
    copy_materials = {m for o in copy_item.collection.objects for m in o.data.materials}
    assert not copy_materials & {m for o in item.collection.objects for m in o.data.materials}
    assert _grass_objects(original) == original_objects
    bpy.ops.windgrass.field_remove()
    assert _grass_objects(original) == original_objects
    assert not _grass_objects(copy)
    # The original still animates: its blades move between frames.
    bpy.context.window.scene = original if bpy.context.window else None
    original.frame_set(2)
    blades = owned.slot_objects(item, owned.ROLE_BLADES)[0]
    before = _positions(blades).copy()
    original.frame_set(9)
    assert not np.array_equal(before, _positions(blades))
    assert all(m.users > 0 for m in item.collection.objects[0].data.materials if m)
    # ... and still draws its flowers: the copy made and removed heads of its own, not the original's
    heads = [m for o in owned.slot_objects(item, owned.ROLE_BLADES).values() for m in o.modifiers
             if m.name == "Windgrass Heads"]
    assert heads and all(m.node_group is not None for m in heads)
    instanced = [i for i in bpy.context.evaluated_depsgraph_get().object_instances if i.is_instance]
    assert instanced


def test_shift_d_copies_are_the_users_own(bridge):
    """A duplicate of a slot object inside the field does not take the slot over; one moved to
    the user's own collection survives Remove."""
    owned, runtime = bridge
    scene, item = _add_field()
    slot = owned.slot_objects(item, owned.ROLE_BLADES)[0]
    inside = slot.copy()
    inside.data = slot.data.copy()
    item.collection.objects.link(inside)
    mine = bpy.data.collections.new("Mine")
    scene.collection.children.link(mine)
    kept = slot.copy()
    kept.data = slot.data.copy()
    mine.objects.link(kept)
    scene.frame_set(3)
    assert owned.slot_objects(item, owned.ROLE_BLADES)[0] is slot
    before = _positions(slot).copy()
    scene.frame_set(11)
    assert not np.array_equal(before, _positions(slot)), "the original slot froze"
    kept_name = kept.name
    bpy.ops.windgrass.field_remove()
    assert kept_name in bpy.data.objects and bpy.data.objects[kept_name].users_collection[0] == mine


def test_renaming_a_scene_keeps_one_runtime(bridge):
    owned, runtime = bridge
    scene, item = _add_field()
    scene.frame_set(2)
    engine = runtime.get_runtime(scene, item).field
    for i in range(4):
        scene.name = f"Meadow {i}"
        scene.frame_set(3 + i)
    assert runtime.get_runtime(scene, item).field is engine
    assert len(runtime.REGISTRY.fields) == 1


def test_a_deleted_scene_leaves_no_runtime(bridge):
    owned, runtime = bridge
    scene, item = _add_field()
    scene.frame_set(2)
    other = bpy.data.scenes.new("Other")
    bpy.context.window.scene = other if bpy.context.window else None
    bpy.data.scenes.remove(scene)
    assert bpy.ops.windgrass.field_add(blocks_x=1, blocks_y=1, cells_per_block=4) == {"FINISHED"}
    assert len(runtime.REGISTRY.fields) == 1


def test_a_setting_that_cannot_be_simulated_hides_the_grass_and_says_why(bridge):
    owned, runtime = bridge
    scene, item = _add_field()
    scene.frame_set(4)
    blades = owned.slot_objects(item, owned.ROLE_BLADES)[0]
    assert np.abs(_positions(blades)).max() > 0.0
    item.lod.blade_far = 1.0  # below blade_near (6 m): the LOD distances are out of order
    scene.frame_set(5)
    error = runtime.field_error(scene, item)
    assert error and "lod.blade_far" in error and "blade_near" in error
    assert np.abs(_positions(blades)).max() == 0.0, "stale grass is still drawn"
    item.lod.blade_far = 12.0
    scene.frame_set(6)
    assert runtime.field_error(scene, item) is None
    assert np.abs(_positions(blades)).max() > 0.0


def test_a_field_without_a_record_is_found_by_its_tags(bridge):
    """Files made before fields recorded what they own: the field's data is found by its tag,
    inside its own collection, and Remove leaves nothing behind."""
    owned, runtime = bridge
    scene, item = _add_field()
    del item[owned.MADE_KEY]
    scene.frame_set(4)
    assert owned.ground_object(item) is not None
    assert owned.slot_objects(item, owned.ROLE_BLADES)
    names = {d.name for d in owned.registered(item).values()}
    assert {"Grass blades", "Grass cards", "Grass ground"} <= names
    bpy.ops.windgrass.field_remove()
    assert not [d for d in (*bpy.data.objects, *bpy.data.meshes, *bpy.data.materials, *bpy.data.images)
                if d.get("wg_uid")]


def test_a_file_saved_with_another_topology_is_rebuilt_on_load(bridge, tmp_path):
    """Files of earlier versions record another slot topology: opening one rebuilds the objects
    (not a frame handler), and the grass shows."""
    owned, runtime = bridge
    scene, item = _add_field()
    item.collection["wg_topology"] = "written by an earlier version"
    path = tmp_path / "old.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(3)
    assert runtime.field_error(scene, item) is None
    assert item.collection["wg_topology"] != "written by an earlier version"
    blades = owned.slot_objects(item, owned.ROLE_BLADES)[0]
    assert np.abs(_positions(blades)).max() > 0.0


def _windgrass_data():
    return sorted(d.name for d in (*bpy.data.objects, *bpy.data.meshes, *bpy.data.materials, *bpy.data.images,
                                   *bpy.data.collections) if d.get("wg_uid"))


def test_remove_after_deleting_the_collection_by_hand_leaves_nothing(bridge):
    """Issue: removing a field after deleting its collection or objects by hand left orphan
    meshes and materials."""
    owned, runtime = bridge
    scene, item = _add_field()
    coll = item.collection
    for obj in list(coll.objects):
        bpy.data.objects.remove(obj)  # what Delete Hierarchy does: objects gone, meshes orphaned
    bpy.data.collections.remove(coll)
    assert item.collection is None and _windgrass_data()  # meshes and materials are left over
    assert bpy.ops.windgrass.field_remove() == {"FINISHED"}
    assert _windgrass_data() == []


def test_rebuild_after_deleting_slots_by_hand_keeps_the_names(bridge):
    """Issue: a Rebuild after deleting slot objects by hand named the new ones 'Grass blades 000.001'."""
    owned, runtime = bridge
    scene, item = _add_field()
    names = sorted(o.name for o in item.collection.objects)
    for obj in [o for o in item.collection.objects if o.get("wg_role") == "blades"]:
        bpy.data.objects.remove(obj)
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    assert sorted(o.name for o in item.collection.objects) == names
    assert not [m for m in bpy.data.meshes if m.users == 0]


def test_duplicate_field_gives_a_working_field_and_copies_of_objects_are_named(bridge, drawn, tmp_path):
    """Issue: Shift+D on "Grass ground" and File > Append of a field's collection gave a bare green
    slab: no field, no message. Duplicate Field gives a second working field (its own uid, the same
    settings, beside the first); a Shift+D copy and an appended collection are named in the panel's
    notes as copies that are not fields."""
    import bpy
    import numpy as np

    owned, runtime = bridge
    from windgrass.grass_addon.bridge import properties

    assert bpy.ops.windgrass.field_add(blocks_x=2, blocks_y=2, cells_per_block=8) == {"FINISHED"}
    scene = bpy.context.scene
    first = scene.windgrass.fields[0]
    first.wind.speed = 7.0
    assert bpy.ops.windgrass.field_duplicate() == {"FINISHED"}
    assert len(scene.windgrass.fields) == 2
    second = scene.windgrass.fields[1]
    assert second.uid != first.uid and second.name != first.name
    assert properties.params_from_settings(second).digest() == properties.params_from_settings(first).digest()
    scene.frame_set(4)
    for item in (first, second):
        assert runtime.field_error(scene, item) is None
        strips = drawn(item).reshape(-1, 6, 2, 3)
        assert (np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0).sum() > 500
    offset = (owned.ground_object(second).matrix_world.translation.x
              - owned.ground_object(first).matrix_world.translation.x)
    assert offset > 1.6  # beside it (a 1.6 m field), not on top
    assert owned.orphan_notes(scene) == []
    bpy.ops.object.select_all(action="DESELECT")
    ground = owned.ground_object(first)
    ground.select_set(True)
    bpy.context.view_layer.objects.active = ground
    bpy.ops.object.duplicate()
    copy = bpy.context.active_object
    notes = owned.orphan_notes(scene)
    assert len(notes) == 1 and f"'{copy.name}' is a copy of a grass field's ground, not a field" in notes[0]
    assert "Duplicate Field" in notes[0]
    path = tmp_path / "source.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.append(directory=str(path) + "/Collection/", filename="Grass")  # the first field's collection
    appended = owned.orphan_notes(bpy.context.scene)
    assert appended and "not a field" in appended[0], appended


def test_duplicating_the_first_of_several_fields_again_and_again_keeps_blender_alive(bridge, drawn):
    """Issue #37 item 1: four fields, then Duplicate Field on the first: the fifth duplicate killed
    Blender (the operator kept the active field's item across ``fields.add()``, which moves the
    items). Every copy is a working field whose grass Blender draws, beside its source."""
    owned, runtime = bridge
    scene = bpy.context.scene
    for _ in range(4):
        _add_field()
    for n in range(6):
        scene.windgrass.active_index = 0
        assert bpy.ops.windgrass.field_duplicate() == {"FINISHED"}
        assert len(scene.windgrass.fields) == 5 + n
    scene.frame_set(3)
    names = [f.name for f in scene.windgrass.fields]
    assert len(set(names)) == len(names) == 10 and len({f.uid for f in scene.windgrass.fields}) == 10
    for item in scene.windgrass.fields:
        assert runtime.field_error(scene, item) is None
        strips = drawn(item).reshape(-1, 6, 2, 3)
        assert (np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0).sum() > 500, item.name
    first = owned.ground_object(scene.windgrass.fields[0]).matrix_world.translation.x
    copies = [owned.ground_object(f).matrix_world.translation.x for f in scene.windgrass.fields[4:]]
    assert all(x - first > 1.6 for x in copies)  # beside the first (a 1.6 m field), not on top


def test_duplicating_a_field_on_a_terrain_puts_the_copy_beside_it(bridge, drawn):
    """Issue #37 item 1: on a terrain the copy landed on top of the original. It grows on a linked
    copy of the terrain beside it: its drawn blades stand where the original's do, moved along X by
    more than the terrain's width."""
    owned, runtime = bridge
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=10, size=3.0)
    hill = bpy.context.active_object
    hill.data.vertices[55].co.z = 0.6
    assert bpy.ops.windgrass.field_add(use_selected_mesh=True, cells_per_block=8) == {"FINISHED"}
    scene = bpy.context.scene
    assert bpy.ops.windgrass.field_duplicate() == {"FINISHED"}
    first, second = scene.windgrass.fields
    assert second.terrain is not None and second.terrain != hill and second.terrain.data == hill.data
    scene.frame_set(1)
    roots = [drawn(item).reshape(-1, 6, 2, 3)[:, 0].mean(axis=1) for item in (first, second)]
    grown = [r[np.ptp(drawn(item).reshape(-1, 12, 3), axis=1).max(axis=1) > 0] for r, item in
             zip(roots, (first, second))]
    assert len(grown[0]) > 500 and len(grown[1]) == len(grown[0])
    shift = grown[1].mean(axis=0) - grown[0].mean(axis=0)
    assert shift[0] > 3.0 and abs(shift[1]) < 0.05 and abs(shift[2]) < 0.05


def test_duplicates_are_named_as_blender_names_copies_and_remove_takes_the_terrain_copy_it_made(bridge, drawn):
    """Issue #63 item 5: the copy of "Grass.001" was named "Grass.001.001" (Blender's own copy of
    Cube.001 is Cube.002), and Remove Field left behind the linked terrain Duplicate made for the
    copy. A copy's copy is numbered on; removing the copy removes its terrain (the original's mesh
    stays, with the original field on it), and Ctrl+Z brings both back."""
    owned, runtime = bridge
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=2.0)
    hill = bpy.context.active_object
    assert bpy.ops.windgrass.field_add(use_selected_mesh=True, cells_per_block=8) == {"FINISHED"}
    scene = bpy.context.scene
    assert bpy.ops.windgrass.field_duplicate() == {"FINISHED"}
    assert bpy.ops.windgrass.field_duplicate() == {"FINISHED"}  # (the copy is active: its copy)
    names = [f.name for f in scene.windgrass.fields]
    assert names == ["Grass", "Grass.001", "Grass.002"], names
    copy = scene.windgrass.fields[2].terrain
    assert copy is not None and copy != hill and copy.data == hill.data
    copy_name = copy.name
    before = {o.name for o in bpy.data.objects}
    bpy.ops.ed.undo_push(message="before remove")
    assert bpy.ops.windgrass.field_remove() == {"FINISHED"}
    gone = before - {o.name for o in bpy.data.objects}
    assert copy_name in gone and hill.name not in gone, gone
    assert hill.data is not None and len(bpy.data.meshes[hill.data.name].vertices) == 49
    scene.frame_set(2)
    first = scene.windgrass.fields[0]
    assert runtime.field_error(scene, first) is None
    assert (np.ptp(drawn(first).reshape(-1, 12, 3), axis=1).max(axis=1) > 0).sum() > 100
    bpy.ops.ed.undo_push(message="remove")  # (as the window pushes after an operator)
    bpy.ops.ed.undo()
    assert copy_name in {o.name for o in bpy.data.objects}
    assert [f.name for f in bpy.context.scene.windgrass.fields] == names
