"""Colliders and force fields in Blender (bridge/tracks.py): a keyed ball parts and tramples the
grass, its motion is sampled once and saved with the file, frame N alone equals frame N of a
sequence; Blender's force fields blow the grass the way they move Blender's own particles.

The field: 4 x 4 blocks of 8 cells of 0.1 m (3.2 m square), 4 blades a cell, calm air.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from mathutils import Euler


@pytest.fixture
def bridge(with_bridge):
    from windgrass.grass_addon.bridge import properties, runtime

    return properties, runtime


def _field(bridge, **wind):
    properties, runtime = bridge
    assert bpy.ops.windgrass.field_add(blocks_x=4, blocks_y=4, cells_per_block=8, blades_per_cell=4,
                                       edge=0.0) == {"FINISHED"}  # (a 3.2 m field: no thinning edge)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 48
    item = scene.windgrass.fields[-1]
    with properties.batch(item):
        item.wind.speed = wind.get("speed", 0.0)
        item.wind.turbulence = wind.get("turbulence", 0.0)
        item.field.clumping = 0.0  # (each blade in its own cell: the tests pick blades by where they stand)
    return scene, item


def _ball(radius=0.3, keys=((1, (-1.2, 0.0, 0.3)), (25, (1.2, 0.0, 0.3)))):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=32, ring_count=16)
    ball = bpy.context.active_object
    for frame, where in keys:
        ball.location = where
        ball.keyframe_insert("location", frame=frame)
    coll = bpy.data.collections.new("Colliders")
    bpy.context.scene.collection.children.link(coll)
    coll.objects.link(ball)
    return ball, coll


def _strips(drawn, scene, item, frame):
    """(blades, joints, 2, 3): the blade strips Blender draws at ``frame`` (evaluated meshes)."""
    scene.frame_set(frame)
    n = item.blade.segments
    return drawn(item).reshape(-1, n + 1, 2, 3)


def _tips(drawn, scene, item, frame):
    return _strips(drawn, scene, item, frame)[:, -1].mean(axis=1)


def test_a_keyed_ball_parts_the_grass_and_its_motion_is_saved(bridge, drawn, tmp_path):
    """The ball (r = 0.3 m) rolls from x = -1.2 to 1.2 m over frames 1-25. Frame 13: no blade tip
    Blender draws is inside it by more than the tolerance (and 5 mm: the mesh's facets); without
    the collider over 50 tips would be inside. The motion is sampled once,
    stored with the field (saved and read back, frame 20 the same, no new sampling)."""
    _, runtime = bridge
    scene, item = _field(bridge)
    ball, coll = _ball()
    before = _tips(drawn, scene, item, 13)
    centre = np.array([0.0, 0.0, 0.3])
    inside_before = np.sum(np.linalg.norm(before - centre, axis=1) < 0.3)
    assert inside_before > 50
    item.collider_collection = coll  # (background Blender samples the motion at once)
    assert "wg_track" in item.collection
    tips = _tips(drawn, scene, item, 13)
    depth = 0.3 - np.linalg.norm(tips - centre, axis=1)
    assert depth.max() < 0.005 + item.interaction.tolerance, depth.max()
    frame20 = _tips(drawn, scene, item, 20).copy()
    path = str(tmp_path / "ball.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    sampled = []
    original = runtime.tracks.sample
    runtime.tracks.sample = lambda *a, **k: sampled.append(1) or original(*a, **k)
    try:
        again = _tips(drawn, scene, item, 20)
    finally:
        runtime.tracks.sample = original
    assert not sampled and np.array_equal(again, frame20)


def test_the_trail_is_trampled_and_frame_n_alone_equals_the_sequence(bridge, drawn):
    """Frame 30 (the ball stopped at x = 1.2 m at frame 25): blades along its path near x = 0 lie
    flatter than the grass far from it, leaning along +x; a fresh runtime seeking frame 30 alone
    draws the same vertices as one stepped through 1-30."""
    properties, runtime = bridge
    scene, item = _field(bridge)
    _, coll = _ball()
    item.collider_collection = coll
    for frame in range(1, 30):
        scene.frame_set(frame)
    seq = _strips(drawn, scene, item, 30).copy()
    runtime.reset_field(scene, item)  # a fresh runtime seeks frame 30 alone
    alone = _strips(drawn, scene, item, 30)
    assert np.array_equal(seq, alone)
    tips = alone[:, -1].mean(axis=1)
    roots = alone[:, 0].mean(axis=1)
    height = tips[:, 2] - roots[:, 2]
    trail = (np.abs(roots[:, 0]) < 0.3) & (np.abs(roots[:, 1]) < 0.1)
    away = np.abs(roots[:, 1]) > 1.0
    assert np.median(height[trail]) < 0.5 * np.median(height[away])
    assert np.median(tips[trail, 0] - roots[trail, 0]) > 0.1


def _balls(spheres, segments=32):
    """Static UV spheres (centre, radius) in a new collection "Colliders"."""
    coll = bpy.data.collections.new("Colliders")
    bpy.context.scene.collection.children.link(coll)
    for centre, radius in spheres:
        bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=centre, segments=segments,
                                             ring_count=segments // 2)
        ball = bpy.context.active_object
        for c in list(ball.users_collection):
            c.objects.unlink(ball)
        coll.objects.link(ball)
    return coll


def _assert_clear_of(strips, rest, spheres, tolerance):
    """What a person expects of grass and balls, on the drawn strips (blades, joints, 2, 3), against
    ``rest``, the same field's strips without the balls: no vertex of a drawn blade inside any ball
    beyond the tolerance; roots where they grew; every segment within 2 % of its length; nothing
    below the ground (z = 0). A blade rooted inside a ball is drawn as nothing (a point), and so
    are the few with a joint no turn takes out of the balls (at most 2 % of those shown)."""
    joints, rest_joints = strips.mean(axis=2), rest.mean(axis=2)
    np.testing.assert_allclose(joints[:, 0], rest_joints[:, 0], atol=1e-5)  # roots where they grew
    shown = np.ptp(rest.reshape(len(rest), -1, 3), axis=1).max(axis=1) > 0  # (FREE positions are points)
    drawn_now = np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0
    seg = np.linalg.norm(np.diff(joints, axis=1), axis=-1)
    rest_seg = np.linalg.norm(np.diff(rest_joints, axis=1), axis=-1)
    both = shown & drawn_now
    assert both.sum() > 0.5 * shown.sum()
    assert np.all(np.abs(seg[both] / rest_seg[both] - 1.0) < 0.02)
    assert joints[both, :, 2].min() > -1e-3
    v = strips[both].reshape(-1, 3)
    rooted_at = np.zeros(len(strips), bool)
    for centre, radius in spheres:
        depth = radius - np.linalg.norm(v - np.asarray(centre), axis=1)
        assert depth.max() < tolerance, (centre, radius, depth.max())
        rooted_at |= np.linalg.norm(rest[:, 0] - np.asarray(centre), axis=-1).min(axis=1) < radius
    trapped = shown & ~drawn_now & ~rooted_at  # not drawn, not rooted in a ball: nowhere to go
    assert trapped.sum() <= 0.02 * shown.sum(), (trapped.sum(), shown.sum())


def test_what_blender_draws_of_a_rolling_ball_stays_out_of_it(bridge, drawn):
    """A keyed ball (r = 0.3 m) rolls through calm grass: at frames 7, 13 and 19 the meshes Blender
    draws hold no vertex inside it beyond the tolerance (plus 5 mm for the sphere mesh's facets),
    the roots stand where they grew, every segment keeps its length, nothing is below the ground."""
    _, runtime = bridge
    scene, item = _field(bridge)
    ball, coll = _ball()
    rest = _strips(drawn, scene, item, 1).copy()  # calm air: every frame's rest pose
    item.collider_collection = coll
    for frame in (7, 13, 19):
        strips = _strips(drawn, scene, item, frame)
        centre = tuple(ball.matrix_world.translation)
        _assert_clear_of(strips, rest, [(centre, 0.3)], 0.005 + item.interaction.tolerance)


def test_a_ball_half_sunk_in_the_ground_sits_on_the_grass(bridge, drawn):
    """A ball of 0.4 m whose centre is 0.1 m below the ground: the blades around it bend over it,
    those rooted under it are drawn as nothing; no root is lifted onto it."""
    _, runtime = bridge
    scene, item = _field(bridge)
    rest = _strips(drawn, scene, item, 5).copy()
    item.collider_collection = _balls([((0.0, 0.0, -0.1), 0.4)])
    strips = _strips(drawn, scene, item, 5)
    _assert_clear_of(strips, rest, [((0.0, 0.0, -0.1), 0.4)], 0.005 + item.interaction.tolerance)
    assert (np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) == 0).sum() > 100


def test_fifty_overlapping_balls_crowd_the_grass_without_a_tip_in_any(bridge, drawn):
    """50 balls (r = 0.08-0.3 m) crowded over the middle of the field, overlapping, some sunk in
    the ground: cleared all at once, no blade is pushed from one ball into another."""
    _, runtime = bridge
    scene, item = _field(bridge)
    scene.frame_end = 6
    rng = np.random.default_rng(12)
    spheres = [((float(x), float(y), float(z)), float(r)) for x, y, z, r in
               zip(rng.uniform(-0.8, 0.8, 50), rng.uniform(-0.8, 0.8, 50), rng.uniform(-0.05, 0.35, 50),
                   rng.uniform(0.08, 0.3, 50))]
    rest = _strips(drawn, scene, item, 3).copy()
    item.collider_collection = _balls(spheres, segments=24)
    strips = _strips(drawn, scene, item, 3)
    _assert_clear_of(strips, rest, spheres, 0.008 + item.interaction.tolerance)


def _cell_bends(runtime, scene, item, frame):
    scene.frame_set(frame)
    rt = runtime.get_runtime(scene, item)
    assert rt is not None, runtime.field_error(scene, item)
    return rt.field.layout.cell_center.astype(np.float64), rt.field.cells.bend.sum(axis=1)


def _force_field(kind, location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0), **settings):
    bpy.ops.object.effector_add(type=kind, location=location, rotation=rotation)
    obj = bpy.context.active_object
    for key, value in settings.items():
        setattr(obj.field, key, value)
    coll = bpy.data.collections.new("Fields")
    bpy.context.scene.collection.children.link(coll)
    for c in list(obj.users_collection):
        c.objects.unlink(obj)
    coll.objects.link(obj)
    return obj, coll


def _particle_drift(coll, points, frames=3):
    """(start (k, 3), drift (k, 3)) of Blender's particles born at rest at ``points`` (k, 3), no
    gravity, in the force fields of ``coll``, after ``frames`` frames (the oracle)."""
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Emitter")
    mesh.from_pydata([tuple(map(float, p)) for p in points], [], [])
    emitter = bpy.data.objects.new("Emitter", mesh)
    scene.collection.objects.link(emitter)
    ps = emitter.modifiers.new("P", "PARTICLE_SYSTEM").particle_system.settings
    ps.count, ps.frame_start, ps.frame_end, ps.lifetime = len(points), 1, 1, 200
    ps.emit_from, ps.use_emit_random, ps.normal_factor = "VERT", False, 0.0
    ps.effector_weights.gravity = 0.0
    ps.effector_weights.collection = coll
    positions = []
    for f in range(1, frames + 1):
        scene.frame_set(f)
        if f in (1, frames):
            parts = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get()).particle_systems[0].particles
            positions.append(np.array([p.location[:] for p in parts]))
    return positions[0], positions[1] - positions[0]


AS_ADDED = {  # each type where Add > Force Field puts it and how it is turned: its settings are Blender's
    "VORTEX": ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), "PLANE"),
    "FORCE": ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), "POINT"),
    "WIND": ((0.0, 0.0, 0.0), (0.0, math.radians(90.0), math.radians(30.0)), "PLANE"),  # (blowing along +X 30)
    "TURBULENCE": ((0.3, -0.2, 0.0), (0.0, 0.0, 0.0), "POINT"),
}


@pytest.mark.parametrize("kind", sorted(AS_ADDED))
def test_force_fields_as_blender_adds_them_move_the_grass_as_blenders_particles(bridge, drawn, kind):
    """Blender is the oracle: every type of force field the grass feels, with the settings Add >
    Force Field gives it (a Vortex of Shape Plane: a turn and an equal pull inwards; a Force
    pushing outwards; a Wind of Shape Plane, turned to blow across the field; a Turbulence of
    eddies of size 0, Blender's noise): particles born at rest at the centres of cells 0.4-1 m from
    the field's centre, at half the grass's height, drift where the tips Blender draws of the
    blades rooted in those cells move from where they stand without the field (within 15 degrees)."""
    _, runtime = bridge
    scene, item = _field(bridge)
    rest = _strips(drawn, scene, item, 24).copy()
    location, rotation, shape = AS_ADDED[kind]
    obj, coll = _force_field(kind, location=location, rotation=rotation)
    assert (obj.field.shape, obj.field.strength) == (shape, 1.0)
    item.effector_collection = coll
    strips = _strips(drawn, scene, item, 24)
    roots, moved = rest[:, 0].mean(axis=1)[:, :2], (strips[:, -1] - rest[:, -1]).mean(axis=1)[:, :2]
    rt = runtime.get_runtime(scene, item)
    layout, half = rt.field.layout, 0.5 * rt.params.field.cell_size
    xy = layout.cell_center.astype(np.float64)
    r = np.hypot(xy[:, 0], xy[:, 1])
    cells = np.flatnonzero((r > 0.4) & (r < 1.0))[::7]
    points = np.column_stack([xy[cells], layout.cell_ground[cells] + 0.5 * layout.cell_length[cells]])
    starts, drift = _particle_drift(coll, points)
    assert np.allclose(starts, points, atol=1e-5) and len(cells) >= 8
    for cell, start, move in zip(cells, starts, drift):
        rooted = np.all(np.abs(roots - xy[cell]) <= half, axis=1)
        assert rooted.sum() >= 2
        tip = moved[rooted].mean(axis=0)
        cosine = float(np.dot(tip, move[:2]) / (np.linalg.norm(tip) * np.linalg.norm(move[:2])))
        assert cosine > math.cos(math.radians(15.0)), (kind, start, tip, move)


def test_a_wind_field_blows_the_grass_where_it_blows_blenders_particles(bridge):
    """Blender is the oracle: particles born at rest at points of the field, no gravity, in the
    same Wind field (its Z axis turned 30 deg up from +X towards +Y, falloff power 1 from a point
    at x = -2 m): where they drift is where the grass bends (within 10 deg), and both move less far
    from the field's centre."""
    _, runtime = bridge
    scene, item = _field(bridge)
    rotation = Euler((0.0, math.radians(90.0), math.radians(30.0)), "XYZ")  # Z axis -> (cos 30, sin 30, 0)
    wind, coll = _force_field("WIND", location=(-2.0, 0.0, 0.15), rotation=rotation, strength=6.0,
                              falloff_power=1.0, shape="POINT")
    item.effector_collection = coll
    xy, bend = _cell_bends(runtime, scene, item, 24)
    # particles: a grid emitter at the grass's mid-height, all born at frame 1 at rest
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3, size=2.0, location=(0.0, 0.0, 0.15))
    emitter = bpy.context.active_object
    mod = emitter.modifiers.new("P", "PARTICLE_SYSTEM")
    ps = mod.particle_system.settings
    ps.count, ps.frame_start, ps.frame_end, ps.lifetime = len(emitter.data.vertices), 1, 1, 200
    ps.emit_from, ps.use_emit_random, ps.normal_factor = "VERT", False, 0.0
    ps.effector_weights.gravity = 0.0
    ps.effector_weights.collection = coll
    positions = []
    for f in range(1, 13):
        scene.frame_set(f)
        if f in (1, 12):
            depsgraph = bpy.context.evaluated_depsgraph_get()
            parts = emitter.evaluated_get(depsgraph).particle_systems[0].particles
            positions.append(np.array([p.location[:] for p in parts]))
    starts, moved = positions[0], positions[1] - positions[0]
    assert len(starts) == len(emitter.data.vertices)
    assert np.all(np.linalg.norm(moved[:, :2], axis=1) > 1e-3), moved
    for start, drift in zip(starts, moved):
        cell = np.argmin(np.hypot(xy[:, 0] - start[0], xy[:, 1] - start[1]))
        b = bend[cell]
        cosine = float(np.dot(b, drift[:2]) / (np.linalg.norm(b) * np.linalg.norm(drift[:2])))
        assert cosine > math.cos(math.radians(10.0)), (start, b, drift)
    near, far = np.argmin(starts[:, 0]), np.argmax(starts[:, 0])
    near_cell = np.argmin(np.hypot(xy[:, 0] - starts[near, 0], xy[:, 1] - starts[near, 1]))
    far_cell = np.argmin(np.hypot(xy[:, 0] - starts[far, 0], xy[:, 1] - starts[far, 1]))
    assert np.linalg.norm(moved[near]) > np.linalg.norm(moved[far])
    assert np.linalg.norm(bend[near_cell]) > np.linalg.norm(bend[far_cell])


def _grass_shown(drawn, scene, item, frame):
    """How many blades Blender draws at ``frame`` (strips with some area)."""
    strips = _strips(drawn, scene, item, frame)
    return int((np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0).sum())


def test_emptied_collections_keep_the_grass_and_say_so(bridge, drawn, tmp_path):
    """What an artist does to the collections a field reads must never hide its grass: deleting
    the only collider, the field's own collection picked as colliders, a collection of empties,
    the only force field set to None or to a type the grass does not feel, a keep-out object with
    no faces. Each leaves the grass drawn (the same as without it), the panel's notes say what the
    collection gives, and a save and reopen shows the grass too."""
    from windgrass.grass_addon.bridge import maps, tracks

    _, runtime = bridge
    scene, item = _field(bridge)
    everything = _grass_shown(drawn, scene, item, 5)
    ball, coll = _ball()
    item.collider_collection = coll
    bpy.data.objects.remove(ball)
    assert bpy.ops.windgrass.track_update() == {"FINISHED"}  # (the window does it when the edit settles)
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 5) == everything
    assert any("holds nothing: no colliders" in n for n in tracks.notes(item))
    bpy.ops.object.empty_add()
    coll.objects.link(bpy.context.active_object)
    item.collider_collection = coll  # a collection of an empty
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 6) == everything
    item.collider_collection = item.collection  # the field's own collection
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 7) == everything
    assert any("own collection" in n for n in tracks.notes(item))
    item.collider_collection = None
    vortex, fields = _force_field("VORTEX", strength=8.0)
    item.effector_collection = fields
    vortex.field.type = "NONE"
    item.effector_collection = fields
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 8) == everything
    vortex.field.type = "MAGNET"
    item.effector_collection = fields
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 9) == everything
    assert any("Magnet force field, which the grass does not feel" in n for n in tracks.notes(item))
    rocks = bpy.data.collections.new("Rocks")
    scene.collection.children.link(rocks)
    bare = bpy.data.objects.new("Bare", bpy.data.meshes.new("Bare"))  # a mesh with no faces
    rocks.objects.link(bare)
    item.keep_out_collection = rocks
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 10) == everything
    assert any("'Bare' in the keep-out collection has no faces" in n for n in maps.keep_out_notes(item))
    path = str(tmp_path / "emptied.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene, item = bpy.context.scene, bpy.context.scene.windgrass.fields[0]
    assert runtime.field_error(scene, item) is None and _grass_shown(drawn, scene, item, 10) == everything


def test_an_armature_walker_tramples_along_its_feet(bridge):
    """Two feet (boxes of a mesh deformed by an armature): their bones are keyed to walk from
    x = -1 m to x = 1 m over frames 1-25, the armature object stays put. Frame 30: the grass along
    each foot's path (y = +-0.2 m) is flatter than between them (y = 0) and far away, leaning +x."""
    _, runtime = bridge
    scene, item = _field(bridge)
    arm_data = bpy.data.armatures.new("Walker")
    rig = bpy.data.objects.new("Walker", arm_data)
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    for side, y in (("L", 0.2), ("R", -0.2)):
        bone = arm_data.edit_bones.new(f"foot.{side}")
        bone.head, bone.tail = (0.0, y, 0.0), (0.0, y, 0.3)
    bpy.ops.object.mode_set(mode="OBJECT")
    verts, faces, groups = [], [], {}
    for side, y in (("L", 0.2), ("R", -0.2)):
        base = len(verts)
        for dx in (-0.12, 0.12):
            for dy in (-0.06, 0.06):
                for z in (0.0, 0.08):
                    verts.append((dx, y + dy, z))
        groups[side] = list(range(base, base + 8))
        faces += [tuple(base + i for i in f) for f in ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6),
                                                         (0, 2, 6, 4), (1, 5, 7, 3))]
    mesh = bpy.data.meshes.new("Feet")
    mesh.from_pydata(verts, [], faces)
    feet = bpy.data.objects.new("Feet", mesh)
    for side, members in groups.items():
        feet.vertex_groups.new(name=f"foot.{side}").add(members, 1.0, "REPLACE")
    feet.modifiers.new("Armature", "ARMATURE").object = rig
    coll = bpy.data.collections.new("Walkers")
    scene.collection.children.link(coll)
    coll.objects.link(feet)
    for side in ("L", "R"):
        pose = rig.pose.bones[f"foot.{side}"]
        for frame, x in ((1, -1.0), (25, 1.0)):
            pose.location = (x, 0.0, 0.0)  # bone space: X is the world's X for a bone along +Z
            pose.keyframe_insert("location", frame=frame)
    scene.frame_set(13)
    moved = feet.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    assert abs(sum(v.co.x for v in moved.vertices) / len(moved.vertices)) < 0.2  # the feet are mid-way
    feet.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh_clear()
    item.collider_collection = coll
    xy, bend = _cell_bends(runtime, scene, item, 30)
    size = np.hypot(bend[:, 0], bend[:, 1])
    path = (np.abs(np.abs(xy[:, 1]) - 0.2) < 0.05) & (np.abs(xy[:, 0]) < 0.6)
    between = (np.abs(xy[:, 1]) < 0.06) & (np.abs(xy[:, 0]) < 0.6)
    away = np.abs(xy[:, 1]) > 1.0
    assert np.median(size[path]) > 0.8 and np.median(size[path]) > 4 * np.median(size[away])
    assert np.median(size[path]) > 2 * np.median(size[between])
    assert np.median(bend[path, 0]) > 3 * np.median(np.abs(bend[path, 1]))


def test_the_motion_is_not_sampled_again_for_playing_its_keys(bridge):
    """The stored motion's fingerprint reads a keyed object's keys, not where it is at the current
    frame: stepping through the frames leaves it fresh; a new key makes it stale."""
    properties, runtime = bridge
    from windgrass.grass_addon.bridge import tracks

    scene, item = _field(bridge)
    ball, coll = _ball()
    item.collider_collection = coll
    params = properties.params_from_settings(item, scene)
    stored = item.collection[tracks.TRACK_KEY]["fingerprint"]
    for frame in (5, 17, 30):
        scene.frame_set(frame)
        assert tracks.fingerprint(scene, item, params) == stored
    ball.location = (0.0, 1.0, 0.3)
    ball.keyframe_insert("location", frame=40)
    assert tracks.fingerprint(scene, item, params) != stored
    assert runtime.update_track(scene, item) is True


def test_a_wind_field_switched_on_at_a_frame_blows_from_then(bridge):
    """A Wind field whose strength is keyed from 0 to 8 at frame 12: calm grass before, bent
    along the field's direction after; stepping the frames leaves the sampled motion fresh (its
    fingerprint reads the strength's keys, not the strength at the current frame)."""
    properties, runtime = bridge
    from windgrass.grass_addon.bridge import tracks

    scene, item = _field(bridge)
    rotation = Euler((0.0, math.radians(90.0), 0.0), "XYZ")  # Z axis -> +X
    wind, coll = _force_field("WIND", location=(-3.0, 0.0, 0.15), rotation=rotation, strength=0.0)
    wind.field.keyframe_insert("strength", frame=11)
    wind.field.strength = 8.0
    wind.field.keyframe_insert("strength", frame=12)
    item.effector_collection = coll
    params = properties.params_from_settings(item, scene)
    stored = tracks.stored_fingerprint(item)
    _, before = _cell_bends(runtime, scene, item, 8)
    assert tracks.fingerprint(scene, item, params) == stored  # (strength 0 here)
    _, after = _cell_bends(runtime, scene, item, 36)
    assert tracks.fingerprint(scene, item, params) == stored  # (strength 8 here)
    assert np.abs(before).max() < 1e-6
    assert np.median(after[:, 0]) > 0.05 and np.median(after[:, 0]) > 10 * np.median(np.abs(after[:, 1]))


def test_the_far_canopy_shows_a_trail_as_the_grass_does(tmp_path):
    """A ball 2 m wide rolled across a long field 43 m from a 6 m eye, beyond the card range: in
    the all-geometry render its trail reads as a dark band (the flattened floor) with a light one
    just before it (grass lit from the open trail); the LOD render's far canopy shows the same
    bands in the same rows (Cycles, the strip view of headless/lod_compare.py)."""
    import lod_compare

    args = lod_compare.parse_args(["--resolution", "320x180", "--samples", "16", "--out", str(tmp_path)])
    params = lod_compare.scene_params(args, "even", fixed=True, strip_height=6.0)
    assert params.lod.card_far < 30.0
    rolled = params.replace({"interaction.recovery": 10.0, "interaction.colliders": [{"shape": "sphere", "radius": 1.0,
                             "path": [{"time": 0.0, "position": [-9.0, -8.0, 0.8]},
                                      {"time": 1.0, "position": [9.0, -8.0, 0.8]}]}]})
    ratios = {}
    for lod in (True, False):
        plain, = lod_compare.render(params, lod, "sun", [48], tmp_path, "plain")
        trail, = lod_compare.render(rolled, lod, "sun", [48], tmp_path, "trail")
        middle = lod_compare.middle_columns(plain)
        ratios[lod] = trail[:, middle, 1].mean(axis=1) / plain[:, middle, 1].mean(axis=1)
    for lod, ratio in ratios.items():
        dark, light = int(np.argmin(ratio)), int(np.argmax(ratio))
        assert ratio[dark] < 0.85 and ratio[light] > 1.1 and dark < light, (lod, np.round(ratio, 2))
        assert np.all(np.abs(ratio[: dark - 4] - 1.0) < 0.05), (lod, np.round(ratio, 2))  # nothing beyond it
    assert abs(int(np.argmin(ratios[True])) - int(np.argmin(ratios[False]))) <= 2
    assert abs(int(np.argmax(ratios[True])) - int(np.argmax(ratios[False]))) <= 2


def _damage(raw, case):
    """Break the stored track ``raw`` (the ID property ``wg_track``) the way ``case`` says."""
    import json

    effectors = json.loads(raw["effectors"])
    if case == "nan velocity":
        raw["velocity"] = [float("nan")] * len(raw["velocity"])
    elif case == "huge radius":
        raw["radii"] = [1e30] * len(raw["radii"])
    elif case == "short offsets":
        raw["offsets"] = list(raw["offsets"])[:-3]
    elif case == "text for centres":
        raw["centres"] = "oops"
    elif case == "no times":
        del raw["times"]
    elif case == "invalid json":
        raw["effectors"] = "{not json"
    elif case == "unknown key":
        effectors[0][0]["bogus"] = 1
        raw["effectors"] = json.dumps(effectors)
    elif case == "infinite strength":
        effectors[0][0]["strength"] = float("inf")
        raw["effectors"] = json.dumps(effectors)
    elif case == "too few samples":
        raw["effectors"] = json.dumps(effectors[:2])
    elif case == "text for the collider count":
        raw["colliders"] = "many"
    elif case == "one time repeated":
        raw["times"] = [0.5] * len(raw["times"])
    elif case == "a number for a force field":
        effectors[0][0] = 7
        raw["effectors"] = json.dumps(effectors)


@pytest.mark.parametrize("case", ["nan velocity", "huge radius", "short offsets", "text for centres", "no times",
                                  "invalid json", "unknown key", "infinite strength", "too few samples",
                                  "text for the collider count", "one time repeated", "a number for a force field",
                                  "a number for the whole track"])
def test_damaged_stored_motion_is_a_sentence_and_is_sampled_again(bridge, drawn, tmp_path, case):
    """A file whose stored collider and force-field motion was damaged by hand: reopened, the grass
    is drawn with finite vertices and no error, the panel's line says the motion is damaged, and
    Update Motion samples it again (the ball parts the grass once more)."""
    from windgrass.grass_addon.bridge import tracks

    _, runtime = bridge
    scene, item = _field(bridge)
    scene.frame_end = 24
    ball, balls = _ball()
    vortex, fields = _force_field("VORTEX", strength=2.0)
    item.collider_collection, item.effector_collection = balls, fields
    sound = _tips(drawn, scene, item, 13).copy()
    if case == "a number for the whole track":  # (issue #57: an AttributeError)
        item.collection[tracks.TRACK_KEY] = 7
    else:
        _damage(item.collection[tracks.TRACK_KEY], case)
    path = str(tmp_path / "damaged.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene, item = bpy.context.scene, bpy.context.scene.windgrass.fields[0]
    tips = _tips(drawn, scene, item, 13)
    assert runtime.field_error(scene, item) is None and np.isfinite(drawn(item)).all()
    from windgrass.grass_addon.bridge import properties

    note = tracks.status(scene, item, properties.params_from_settings(item, scene))
    assert note and "is damaged" in note and "Update Motion" in note, note
    assert bpy.ops.windgrass.track_update() == {"FINISHED"}
    assert tracks.damage(item) is None
    again = _tips(drawn, scene, item, 13)
    np.testing.assert_allclose(again, sound, atol=1e-6)  # sampled again: the ball and the vortex are back
    assert not np.allclose(tips, sound, atol=1e-4)  # (while damaged, they were left out)


def test_a_large_keyed_collider_is_sampled_once_and_the_grass_clears_it(bridge, drawn):
    """A ball of 32,000 vertices (a rigid collider large enough to be cut into pieces once and
    moved by its matrix each frame) rolls through calm grass: the drawn grass holds no vertex
    inside it beyond the tolerance (plus the pieces' slack), roots where they grew, segments whole."""
    from windgrass.grass_addon.bridge import tracks

    _, runtime = bridge
    scene, item = _field(bridge)
    rest = _strips(drawn, scene, item, 1).copy()
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, segments=256, ring_count=128)
    ball = bpy.context.active_object
    assert len(ball.data.vertices) >= tracks.RIGID_MIN_VERTICES and tracks.rigid(ball)
    for frame, where in ((1, (-1.2, 0.0, 0.3)), (25, (1.2, 0.0, 0.3))):
        ball.location = where
        ball.keyframe_insert("location", frame=frame)
    coll = bpy.data.collections.new("Colliders")
    scene.collection.children.link(coll)
    coll.objects.link(ball)
    item.collider_collection = coll
    for frame in (7, 13, 19):
        strips = _strips(drawn, scene, item, frame)
        _assert_clear_of(strips, rest, [(tuple(ball.matrix_world.translation), 0.3)],
                         0.005 + item.interaction.tolerance)



def test_a_wind_force_field_as_blender_adds_it_is_named_until_turned_to_blow_across(bridge, drawn):
    """Issue #63 item 7: a Wind force field as Blender adds it blows along its Z axis, straight up,
    so the grass hardly moves, and nothing said why. The panel's note names it and says how to
    turn it; turned 90 degrees about X it blows across the calm grass, which leans, and the note
    is gone."""
    import math

    from windgrass.grass_addon.bridge import tracks

    scene, item = _field(bridge)
    calm = _tips(drawn, scene, item, 12).copy()
    wind, fields = _force_field("WIND", strength=6.0)
    item.effector_collection = fields
    assert bpy.ops.windgrass.track_update() == {"FINISHED"}
    upward = _tips(drawn, scene, item, 12).copy()
    note = [n for n in tracks.notes(item) if "blows along its Z axis" in n]
    assert note and f"'{wind.name}'" in note[0] and "points up" in note[0] and "rotate" in note[0], tracks.notes(item)
    wind.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    assert bpy.ops.windgrass.track_update() == {"FINISHED"}
    across = _tips(drawn, scene, item, 12)
    lean = np.linalg.norm((across - calm)[:, :2], axis=1).mean()
    assert np.linalg.norm((upward - calm)[:, :2], axis=1).mean() < 0.2 * lean and lean > 0.01, lean
    assert not [n for n in tracks.notes(item) if "blows along its Z axis" in n]
