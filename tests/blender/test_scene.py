"""The bpy bridge: building a field, driving it per frame, LOD from the camera, renders,
save/reopen, removal and robustness (grass_addon/bridge/scene.py, runtime.py, materials.py,
textures.py). Small fields (2 x 2 blocks of 8 x 8 cells) and tiny renders keep this fast.
"""

from __future__ import annotations

import warnings

import bpy
import numpy as np
import pytest
from mathutils import Vector

ADDON = "windgrass"
BRIDGE = f"{ADDON}.grass_addon.bridge"

RES_X, RES_Y = 96, 54


@pytest.fixture
def bridge(with_bridge):
    """(scene module, runtime module); ``with_bridge`` skips while the engine is incomplete."""
    from windgrass.grass_addon.bridge import owned, runtime

    return owned, runtime


def _add_field(**field_options):
    options = {"blocks_x": 2, "blocks_y": 2, "cells_per_block": 8, "edge": 0.0}  # (a 1.6 m field: no thinning edge)
    options.update(field_options)
    assert bpy.ops.windgrass.field_add(**options) == {"FINISHED"}
    scene = bpy.context.scene
    return scene, scene.windgrass.fields[-1]


def _owned(item, role):
    return sorted((o for o in item.collection.objects if o.get("wg_role") == role), key=lambda o: o["wg_slot"])


def _positions(obj) -> np.ndarray:
    mesh = obj.data
    out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def _all_positions(item) -> dict[str, np.ndarray]:
    return {o.name: _positions(o) for o in item.collection.objects if o.get("wg_role") in ("blades", "cards")}


def _reopened(path, expected):
    """Open ``path``; its first field draws ``expected`` (``_all_positions``) at once. Returns the field."""
    bpy.ops.wm.open_mainfile(filepath=str(path))
    item = bpy.context.scene.windgrass.fields[0]
    got = _all_positions(item)
    assert got.keys() == expected.keys()
    for name, pos in expected.items():
        np.testing.assert_allclose(got[name], pos, atol=1e-6, err_msg=name)
    return item


def _camera(scene, location, target=(0.0, 0.0, 0.1), lens=35.0):
    data = bpy.data.cameras.new("Test camera")
    data.lens = lens
    cam = bpy.data.objects.new("Test camera", data)
    scene.collection.objects.link(cam)
    _aim(cam, location, target)
    scene.camera = cam
    return cam


def _aim(cam, location, target):
    cam.location = location
    direction = Vector(target) - Vector(location)
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def _stage(scene):
    """Camera looking down at the 1.6 m field, a sun and a grey-blue (non-green) world."""
    _camera(scene, (0.0, -2.2, 1.2))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.7, 0.2, 0.5)
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("World")
    world.color = (0.35, 0.4, 0.5)
    if world.node_tree is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            world.use_nodes = True  # Blender < 5 (5.0 gives every world a node tree)
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    background.inputs["Color"].default_value = (0.35, 0.4, 0.5, 1.0)
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y = RES_X, RES_Y
    scene.render.resolution_percentage = 100


# --------------------------------------------------------------------------------------------
# Pure helpers (no scene needed)


# --------------------------------------------------------------------------------------------
# Building and per-frame updates


def test_field_add_builds_collection_ground_and_slot_pools(bridge):
    owned, runtime = bridge
    scene, item = _add_field()
    coll = item.collection
    assert coll is not None and coll.name in scene.collection.children
    ground = owned.ground_object(item)
    # 2 blocks of 8 cells of 0.1 m: a 1.6 m square centred on the origin.
    assert ground.dimensions.x == pytest.approx(1.6, abs=1e-5)
    assert ground.dimensions.y == pytest.approx(1.6, abs=1e-5)
    assert tuple(ground.matrix_world.translation) == pytest.approx((0.0, 0.0, 0.0))
    blades, cards = _owned(item, "blades"), _owned(item, "cards")
    # The whole field lies well within d_g2 = 12 m of any camera near it: a position per block,
    # all 4 in one object (blocks of 1536 blade / 256 card vertices: 16 / 96 would fit one).
    assert len(blades) == 1 and len(cards) == 1
    rt = runtime.get_runtime(scene, item)
    layout = rt.field.layout
    assert (rt.blades.shape.k, rt.cards.shape.k) == (4, 4)
    per_block_verts = layout.blades_per_block * (layout.segments + 1) * 2
    assert all(len(o.data.vertices) == 4 * per_block_verts for o in blades)
    assert all(len(o.data.polygons) == 4 * layout.blades_per_block * layout.segments for o in blades)
    assert all(len(o.data.vertices) == 4 * layout.cells_per_block_total * 4 for o in cards)
    assert all(o.parent == ground for o in blades + cards)
    # the blades carry the flower heads' modifier alone (Add Grass Field's daisies and buttercups)
    assert all(o.modifiers.keys() == ["Windgrass Heads"] for o in blades) and not any(o.modifiers for o in cards)
    assert scene.render.use_lock_interface
    # Materials and the packed, generated card texture.
    mats = {o.active_material.name for o in blades + cards + [ground]}
    assert len(mats) == 3
    card_mat = cards[0].active_material
    images = [n.image for n in card_mat.node_tree.nodes if n.type == "TEX_IMAGE"]
    assert images and images[0].packed_file is not None
    assert all(not m.use_backface_culling for m in (blades[0].active_material, card_mat))


def test_canopy_material_follows_the_lod_distances(bridge):
    """K_t of eq 10 is computed in the far canopy's shader from the view distance: its Map Range
    goes from d_s1 to d_s2 and follows the settings; with the LOD off the far texture never shows.
    The canopy lies above the ground at the sward's height."""
    from windgrass.grass_addon import meadow, sward
    from windgrass.grass_addon.bridge import materials, properties

    owned, _ = bridge
    scene, item = _add_field()
    canopy = [m for m in bpy.data.materials if m.get("wg_role") == "canopy_material"][0]
    ground = owned.ground_object(item)
    assert [m.get("wg_role") for m in ground.data.materials] == ["ground_material", "canopy_material"]
    z = _positions(ground)[:, 2]
    params = properties.params_from_settings(item, scene)
    height, top = sward.canopy_height(params), sward.fringe_top(params)
    longest = max(r["length"] + 4.0 * r["length_variation"] for r in params.species())  # (blocks.Species)
    tallest = longest * (1.0 + meadow.PATCH_LENGTH * params.field.patchiness)  # no tip higher
    assert 0.05 < height < sward.sward_top(params) <= top < tallest
    # the ground, the canopy plane and the top of its fringe along the field's edge (the tallest tip,
    # in the tallest patch)
    np.testing.assert_allclose(np.unique(np.round(z, 5)), [0.0, height, top], atol=1e-5)
    # the shader knows each corner's height above the ground, and which corners are the fringe's
    sward_z = np.empty(2 * len(ground.data.loops))
    ground.data.uv_layers[materials.UV_SWARD_Z].data.foreach_get("uv", sward_z)
    sward_z = sward_z.reshape(-1, 2)
    corner_z = z[[loop.vertex_index for loop in ground.data.loops]]
    canopy_corners = np.repeat([p.material_index == 1 for p in ground.data.polygons],
                               [p.loop_total for p in ground.data.polygons])
    np.testing.assert_allclose(sward_z[canopy_corners, 1], corner_z[canopy_corners], atol=1e-5)
    assert set(np.unique(sward_z[canopy_corners & (corner_z > height + 1e-4), 0])) == {1.0}
    # its silhouette depth profile, from the ground (most) to the tallest tip (none)
    curve = canopy.node_tree.nodes[materials.NODE_SWARD_PROFILE].mapping.curves[0]
    points = np.array([pt.location[:] for pt in curve.points])
    assert points[0, 0] == 0.0 and points[-1, 0] == pytest.approx(1.0)
    assert points[0, 1] == pytest.approx(1.0) and points[-1, 1] == pytest.approx(0.0, abs=1e-6)
    assert np.all(np.diff(points[:, 1]) <= 1e-6)
    kt = canopy.node_tree.nodes[materials.NODE_KT]
    assert kt.clamp
    assert (kt.inputs["From Min"].default_value, kt.inputs["From Max"].default_value) == (25.0, 40.0)
    item.lod.card_near = 30.0  # the property update rewrites the field and its materials
    assert kt.inputs["From Min"].default_value == pytest.approx(30.0)
    item.lod.enabled = False
    assert kt.inputs["From Min"].default_value >= materials.FAR_AWAY


def test_resizing_the_field_rebuilds_slots_where_the_user_placed_it(bridge):
    owned, runtime = bridge
    scene, item = _add_field()
    owned.ground_object(item).location = (5.0, 0.0, 0.0)
    item.field.blocks_x = 3  # the property update rebuilds: 3 x 2 blocks now
    bpy.context.view_layer.update()  # (the ground object stays: its new mesh's bounds once evaluated)
    ground = owned.ground_object(item)
    assert tuple(ground.location) == pytest.approx((5.0, 0.0, 0.0))
    assert ground.dimensions.x == pytest.approx(2.4, abs=1e-5)
    # 6 blocks of 128 blades (1536 vertices): up to 16 fit one object, all 6 share one.
    assert len(_owned(item, "blades")) == 1 and len(_owned(item, "blades")[0].data.vertices) == 6 * 1536
    assert len([m for m in bpy.data.meshes if m.users == 0]) == 0  # old slot meshes are gone
    # Blades follow the ground: every blade root lies on the moved plane.
    scene.frame_set(4)
    world = np.array(_owned(item, "blades")[0].matrix_world)
    n = runtime.get_runtime(scene, item).field.layout.segments
    roots = _positions(_owned(item, "blades")[0]).reshape(-1, n + 1, 2, 3)[:, 0].mean(axis=1)
    roots_world = roots @ world[:3, :3].T + world[:3, 3]
    assert roots_world[:, 0].min() >= 5.0 - 1.2 - 1e-4 and roots_world[:, 0].max() <= 5.0 + 1.2 + 1e-4


def test_ui_edits_are_coalesced_until_they_settle(bridge):
    """In the UI a dragged slider marks the field dirty at every step; one rebuild follows."""
    import time

    _, runtime = bridge
    scene, item = _add_field()
    before = runtime.get_runtime(scene, item).digest
    for turbulence in (1.25, 1.375, 1.5):  # three slider steps
        item.wind["turbulence"] = turbulence  # raw ID-property write: no update callback of its own
        runtime.mark_dirty(scene, item, defer=True)
    assert runtime.get_runtime(scene, item).digest == before  # nothing rebuilt while dragging
    assert runtime.flush_pending() is not None  # still settling: the timer runs again
    time.sleep(runtime.EDIT_SETTLE_S + 0.05)
    assert runtime.flush_pending() is None
    runtime.shown_when_done(scene, item)  # (the new run is made on a thread: one, for the last value)
    assert runtime.get_runtime(scene, item).digest != before
    assert runtime.get_runtime(scene, item).field.sim.params.wind.turbulence == pytest.approx(1.5)


def test_frame_change_refreshes_bounds_of_written_meshes(bridge):
    """Blender must see the new positions (bounds), or renders depend on earlier frames."""
    scene, item = _add_field()
    for frame in (1, 40):
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for obj in _owned(item, "blades"):
            points = _positions(obj)
            box = np.array(obj.evaluated_get(depsgraph).bound_box)
            assert (points.min(axis=0) >= box.min(axis=0) - 1e-5).all()
            assert (points.max(axis=0) <= box.max(axis=0) + 1e-5).all()


def test_frame_change_sways_tips_and_keeps_roots(bridge):
    _, runtime = bridge
    scene, item = _add_field()
    rt = runtime.get_runtime(scene, item)
    engine = rt.field
    n = rt.field.layout.segments
    scene.frame_set(1)
    before = _positions(_owned(item, "blades")[0]).reshape(-1, n + 1, 2, 3)
    scene.frame_set(30)
    after = _positions(_owned(item, "blades")[0]).reshape(-1, n + 1, 2, 3)
    # Roots are planted: the centre of joint 0 stays on the ground where it was (the root edge
    # may turn about it with the blade's twist, so its two corners can move).
    np.testing.assert_allclose(after[:, 0].mean(axis=1), before[:, 0].mean(axis=1), atol=1e-5)
    assert np.abs(after[:, 0, :, 2]).max() < 1e-6
    # Tips move in a 4.4 m/s breeze with 1.2 m/s turbulence over 1.2 s: by millimetres at least.
    tip_motion = np.linalg.norm(after[:, -1] - before[:, -1], axis=-1)
    assert tip_motion.max() > 1e-3
    # Tips stay within a blade length of their roots (rigid segments, nothing stretches).
    length = np.linalg.norm(after[:, -1].mean(axis=1) - after[:, 0].mean(axis=1), axis=-1)
    assert length.max() <= float(rt.field.layout.blade_length.max()) * 1.01
    assert runtime.get_runtime(scene, item).field is engine  # same params: the engine is kept


def test_slot_object_shows_exactly_the_chosen_blocks(bridge):
    """An object holding k positions shows the chosen blocks' blades at its shown positions (every
    root inside that block's square of ground, every blade standing), with their species colours,
    and collapsed rows (one point, no colour) at FREE positions."""
    owned, runtime = bridge
    # 6 blocks of 16 x 16 cells (6144 vertices each): k = 4, 2 objects; no camera: all shown.
    scene, item = _add_field(blocks_x=3, cells_per_block=16, clumping=0.0)  # (roots in their blocks)
    scene.frame_set(7)
    rt = runtime.get_runtime(scene, item)
    layout = rt.field.layout
    k = rt.blades.shape.k
    assert k == 4 and rt.blades.blocks.tolist() == [0, 1, 2, 3, 4, 5]
    assert rt.blades.state.shown.tolist() == [0, 1, 2, 3, 4, 5, -1, -1]  # then FREE
    second = _owned(item, "blades")[1]  # positions 4..7: blocks 4, 5, then two FREE
    rows = _positions(second).reshape(k, -1, 3)
    for i, block in enumerate((4, 5)):
        _assert_holds_block(item, rows[i], block)
    assert np.abs(rows[2:]).max() == 0.0  # FREE: every vertex at the origin (zero area)
    # (position, blade, corner, (r, g) | (b, shade)): the species colour and shade of each blade
    rg, bs = (_uv(second, name).reshape(k, layout.blades_per_block, -1, 2) for name in ("wg_tint_rg", "wg_tint_bs"))
    for i, block in enumerate((4, 5)):
        blades = layout.block_blades(block)
        colour = layout.species_color[layout.blade_species[blades]]
        np.testing.assert_allclose(rg[i, :, 0], colour[:, :2], atol=1e-6)
        np.testing.assert_allclose(bs[i, :, 0, 0], colour[:, 2], atol=1e-6)
        np.testing.assert_allclose(bs[i, :, 0, 1], layout.blade_shade[blades], atol=1e-6)
        # one colour per blade up its stem (dry tips and heads colour its top: meadow.py)
        assert (rg[i, :, :4] == rg[i, :, :1]).all()
    assert np.abs(rg[2:]).max() == 0.0 and np.abs(bs[2:]).max() == 0.0
    # The first object holds blocks 0..3 in order.
    first = _positions(_owned(item, "blades")[0]).reshape(k, -1, 3)
    for block in range(4):
        _assert_holds_block(item, first[block], block)


def _assert_holds_block(item, rows, block):
    """``rows`` (a position's vertices) are the blades of ``block``: roots inside its square of the
    field (blocks of cells_per_block x cell_size, row-major from the field's -x, -y corner, the
    field centred on the origin) and rising from them, each blade drawn (some area)."""
    f = item.field
    edge = f.cells_per_block * f.cell_size
    x0 = -0.5 * f.blocks_x * edge + (block % f.blocks_x) * edge
    y0 = -0.5 * f.blocks_y * edge + (block // f.blocks_x) * edge
    strips = rows.reshape(-1, item.blade.segments + 1, 2, 3)
    roots, tips = strips[:, 0].mean(axis=1), strips[:, -1].mean(axis=1)
    assert len(strips) == f.cells_per_block ** 2 * f.blades_per_cell
    assert np.all((roots[:, 0] >= x0 - 1e-5) & (roots[:, 0] <= x0 + edge + 1e-5))
    assert np.all((roots[:, 1] >= y0 - 1e-5) & (roots[:, 1] <= y0 + edge + 1e-5))
    # each blade drawn (its tip 5 cm or more from its root) and rising from it: in the default gusts
    # about 0.4 % of the blades bend to within 9 degrees of the ground (a long stem 5 cm up)
    assert np.all(np.linalg.norm(tips - roots, axis=1) > 0.05) and np.all(tips[:, 2] > roots[:, 2])


def test_wind_fcurves_become_wind_keys(bridge):
    _, runtime = bridge
    scene, item = _add_field()
    item.wind.speed = 0.0
    item.wind.keyframe_insert("speed", frame=1)
    item.wind.speed = 12.0
    item.wind.keyframe_insert("speed", frame=25)
    scene.frame_set(10)
    rt = runtime.get_runtime(scene, item)
    engine = rt.field
    assert rt.wind_keys is not None
    times = np.array([k[0] for k in rt.wind_keys])
    speeds = np.array([k[1] for k in rt.wind_keys])
    fps = scene.render.fps
    # t = (frame - frame_start) / fps: frame 25 is t = 1 s at 24 fps, where the speed key is 12.
    assert speeds[np.argmin(np.abs(times - (25 - 1) / fps))] == pytest.approx(12.0, abs=1e-4)
    assert speeds[np.argmin(np.abs(times))] == pytest.approx(0.0, abs=1e-4)
    scene.frame_set(11)
    # The animated value changes every frame; the engine (and its simulation) must not be rebuilt.
    assert runtime.get_runtime(scene, item).field is engine


def test_camera_moves_change_lod(bridge):
    """Blades near the camera, cards further out (eqs 7-11): moving the camera from one corner of
    the field to the opposite one moves the blades to the other blocks."""
    owned, runtime = bridge
    scene, item = _add_field(cell_size=0.5)  # 8 m square, blocks of 4 m
    item.lod.blade_near, item.lod.blade_far = 1.0, 2.5
    item.lod.card_near, item.lod.card_far = 6.0, 9.0
    cam = _camera(scene, (-3.5, -3.5, 1.0), target=(0.0, 0.0, 0.0))
    scene.frame_set(2)
    rt = runtime.get_runtime(scene, item)
    layout = rt.field.layout
    corner_block = 0  # block (0, 0) holds the camera's ground point (-3.5, -3.5)
    far_block = layout.n_blocks - 1
    assert corner_block in rt.blades.blocks.tolist()
    assert far_block not in rt.blades.blocks.tolist()  # its nearest point is 3.5 m > d_g2 away
    opacity_near = _card_opacity(item, rt)
    _aim(cam, (3.5, 3.5, 1.0), (0.0, 0.0, 0.0))
    # Moving the camera without a frame change (viewport): the depsgraph update follows it.
    bpy.context.view_layer.update()
    assert far_block in rt.blades.blocks.tolist() and corner_block not in rt.blades.blocks.tolist()
    assert not np.array_equal(opacity_near, _card_opacity(item, rt))
    scene.frame_set(3)
    assert far_block in rt.blades.blocks.tolist() and corner_block not in rt.blades.blocks.tolist()
    # Positions without a block collapse to one point (zero area: nothing drawn).
    k = rt.blades.shape.k
    for obj in _owned(item, "blades"):
        rows = _positions(obj).reshape(k, -1, 3)
        for i, pos in enumerate(rows):
            spread = float(np.ptp(pos, axis=0).max())
            assert (spread > 0.0) == (int(rt.blades.state.shown[obj["wg_slot"] * k + i]) >= 0)



def test_a_small_camera_move_refades_the_cards_it_keeps(bridge):
    """A still camera's LOD weights are worked out once and the cards' opacity is not written
    again; a dolly of half a metre keeps every card block in its slot, yet eq 11's K_b of each
    card changes with its distance: the slots then hold the opacity a fresh build gives there."""
    owned, runtime = bridge
    scene, item = _add_field(cell_size=0.5)  # 8 m square, blocks of 4 m
    item.lod.blade_near, item.lod.blade_far = 1.0, 2.5
    item.lod.card_near, item.lod.card_far = 6.0, 9.0
    cam = _camera(scene, (-3.5, -3.5, 1.0), target=(0.0, 0.0, 0.0))
    for frame in (2, 3):  # (the second frame reuses the first's weights)
        scene.frame_set(frame)
    rt = runtime.get_runtime(scene, item)
    cards_before, opacity_before = rt.cards.blocks.tolist(), _card_opacity(item, rt)
    _aim(cam, (-3.0, -3.5, 1.0), (0.5, 0.0, 0.0))
    scene.frame_set(4)
    assert rt.cards.blocks.tolist() == cards_before  # the same blocks in the same slots
    moved = _card_opacity(item, rt)
    assert not np.allclose(moved, opacity_before, atol=1e-3)
    runtime.build_field(scene, item)  # a fresh runtime at this camera and frame
    np.testing.assert_array_equal(moved, _card_opacity(item, runtime.get_runtime(scene, item)))

def _uv(obj, name) -> np.ndarray:
    data = np.empty(len(obj.data.loops) * 2, dtype=np.float32)
    obj.data.uv_layers[name].data.foreach_get("uv", data)
    return data


def _slot_data(item) -> dict[str, np.ndarray]:
    out = {}
    for obj in item.collection.objects:
        mesh = obj.data
        if obj.get("wg_role") not in ("blades", "cards"):
            continue
        out[f"{obj.name}/position"] = _positions(obj).ravel()
        for layer in mesh.uv_layers:
            if layer.name.startswith("wg_"):
                out[f"{obj.name}/{layer.name}"] = _uv(obj, layer.name)
    return out


def test_animated_camera_lod_and_frames_independent_of_history(bridge):
    """An animated camera drives the LOD at the frame being shown (its matrix is only known after
    evaluation), and every slot holds the same data at frame 4 whether frames 1-3 were visited
    before or not (render farms render frames apart)."""
    owned, runtime = bridge
    scene, item = _add_field(cell_size=0.5)  # 8 m square, blocks of 4 m
    item.lod.blade_near, item.lod.blade_far = 1.0, 2.5
    item.lod.card_near, item.lod.card_far = 6.0, 9.0
    cam = _camera(scene, (-3.5, -3.5, 1.0), target=(0.0, 0.0, 0.0))
    cam.keyframe_insert("location", frame=1)
    cam.location = (3.5, 3.5, 1.0)
    cam.rotation_euler = (Vector((0.0, 0.0, 0.0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.keyframe_insert("location", frame=4)
    cam.keyframe_insert("rotation_euler", frame=4)
    for frame in (1, 2, 3, 4):
        scene.frame_set(frame)
    rt = runtime.get_runtime(scene, item)
    assert rt.blades.blocks.tolist() == [3]  # only the block under the camera at frame 4
    visited = _slot_data(item)
    runtime.build_field(scene, item)  # a fresh runtime straight at frame 4
    fresh = _slot_data(item)
    assert visited.keys() == fresh.keys()
    for key, data in visited.items():
        np.testing.assert_array_equal(fresh[key], data, err_msg=key)


def _card_opacity(item, rt):

    k = rt.cards.shape.k
    out = {}
    for obj in _owned(item, "cards"):
        data = _uv(obj, "wg_fade")[::2]  # (K_b, K_b) per corner; corners and vertices match on cards
        for i, rows in enumerate(data.reshape(k, -1)):
            block = int(rt.cards.state.shown[obj["wg_slot"] * k + i])
            if block >= 0:
                out[block] = rows
    return np.concatenate([out[b] for b in sorted(out)]) if out else np.zeros(0)


# --------------------------------------------------------------------------------------------
# Renders


def _render(scene, path) -> np.ndarray:
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    pixels = np.empty(RES_X * RES_Y * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(RES_Y, RES_X, 4)[..., :3]  # row 0 is the bottom of the image


def _eevee_id() -> str:
    ids = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in ids else "BLENDER_EEVEE"


@pytest.mark.parametrize("engine", ["CYCLES", "EEVEE"])
def test_renders_show_swaying_grass(bridge, engine, tmp_path):
    from windgrass.grass_addon.bridge import properties

    scene, item = _add_field()
    # the paper's even field of the schema's one species, no gust waves: the meadow's tall stems and
    # flowers sway into the top rows, which this test reads as the still sky
    even = properties.params_from_settings(item).replace({"blade.species": [], "field.clumping": 0.0,
                                                         "field.patchiness": 0.0, "blade.dry_tips": 0.0,
                                                         "wind.gust_waves": 0.0})
    properties.apply_params(item, even)
    runtime = bridge[1]
    runtime.update_scene(scene)
    _stage(scene)
    if engine == "CYCLES":
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = 4
    else:
        scene.render.engine = _eevee_id()
        scene.eevee.taa_render_samples = 4
    scene.frame_set(1)
    first = _render(scene, tmp_path / "f1.png")
    scene.frame_set(40)
    second = _render(scene, tmp_path / "f40.png")
    # The camera looks down at the field: the lower third of the image is field, the top rows sky.
    field, sky = first[: RES_Y // 3], first[-6:]
    green = (field[..., 1] > field[..., 0]) & (field[..., 1] > field[..., 2])
    assert green.mean() > 0.5, "the field should read as green grass"
    sky_green = (sky[..., 1] > sky[..., 0]) & (sky[..., 1] > sky[..., 2])
    assert sky_green.mean() < 0.1, "the world is grey-blue, not grass"
    # The grass sways between frames 1 and 40 (1.6 s of a 4.4 m/s breeze): thin blades cross
    # pixels, so a clear share of the field's pixels changes; the sky does not change (Cycles'
    # noise is seeded the same in both frames: at most a level of 8-bit rounding differs).
    changed = np.abs(second - first).max(axis=-1) > 0.02  # 5 levels of 8-bit, beyond noise
    print(f"{engine}: changed share of field pixels {changed[: RES_Y // 3].mean():.3f}, "
          f"of sky pixels {changed[-6:].mean():.3f}")
    assert changed[: RES_Y // 3].mean() > 0.03
    assert changed[-6:].mean() < 0.01


def _meadow_from_inside(bridge, tmp_path, name, setup):
    """The default 2 km scene from a camera 1.2 m up at its centre that ``setup`` shapes, rendered
    at 192 x 108 (Cycles, 4 samples); the image's rows 55-75 % down (the field from a few metres
    out to the card band) in 8 bands left to right, RGB 0..1."""
    from pathlib import Path

    import stage
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties

    _, runtime = bridge
    repo = Path(__file__).resolve().parents[2]
    params = schema.load_toml(repo / "scenes" / "default.toml").replace({
        "camera.mode": "fixed", "render.resolution_x": 192, "render.resolution_y": 108, "render.samples": 4})
    scene = bpy.context.scene
    stage.setup_stage(scene, params)
    cam = scene.camera
    cam.animation_data_clear()
    setup(cam)
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    scene.frame_set(2)
    scene.render.filepath = str(tmp_path / f"{name}.png")
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(scene.render.filepath)
    w, h = image.size
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)[::-1, :, :3]  # row 0 at the top
    bpy.data.images.remove(image)
    return np.array_split(pixels[int(0.55 * h):int(0.75 * h)], 8, axis=1)


def test_a_shifted_lens_shows_grass_in_the_shifted_part_of_the_image(bridge, tmp_path):
    """Issue: with lens shift (shift_x = 0.6) the shifted part of the image showed bare ground
    (culling assumed a centred frustum). Every band of the near field is as green as the rest:
    the floor under culled cards is a dull olive (measured before: the right bands' green excess
    fell to 0.035-0.063 against 0.09 elsewhere)."""
    def shifted(cam):
        cam.location = (0.0, 0.0, 1.2)
        cam.rotation_euler = Vector((0.0, 10.0, -0.9)).to_track_quat("-Z", "Y").to_euler()
        cam.data.shift_x = 0.6

    bands = _meadow_from_inside(bridge, tmp_path, "shift", shifted)
    excess = [float((b[..., 1] - np.maximum(b[..., 0], b[..., 2])).mean()) for b in bands]
    assert min(excess) > 0.7 * float(np.median(excess)), excess


def test_a_panoramic_camera_shows_grass_all_around(bridge, tmp_path):
    """Issue: a panoramic (equirectangular) camera showed grass only in the ~40 degrees ahead.
    Every azimuth is as green as the greenest: blades and cards, not the olive floor under culled
    grass (measured on the old culling: green excess 0.021 behind the camera against 0.056-0.070
    ahead; now 0.052-0.083 all around). A mean, so it does not hang on how the denoiser smooths
    4 samples on a given CPU (the per-pixel texture did: 0.016-0.041 on one machine, 0.021-0.041
    on another)."""
    def panoramic(cam):
        cam.location = (0.0, 0.0, 1.2)
        cam.rotation_euler = Vector((0.0, 10.0, 0.0)).to_track_quat("-Z", "Y").to_euler()
        cam.data.type = "PANO"
        if hasattr(cam.data, "panorama_type"):
            cam.data.panorama_type = "EQUIRECTANGULAR"
        else:  # pragma: no cover (Blender < 4.0)
            cam.data.cycles.panorama_type = "EQUIRECTANGULAR"

    bands = _meadow_from_inside(bridge, tmp_path, "pano", panoramic)
    excess = [float((b[..., 1] - np.maximum(b[..., 0], b[..., 2])).mean()) for b in bands]
    assert min(excess) > 0.5 * max(excess), excess


# --------------------------------------------------------------------------------------------
# Files, removal, undo, damage


def test_save_and_reopen_gives_the_same_frame(bridge, tmp_path):
    _, runtime = bridge
    scene, item = _add_field()
    scene.frame_set(12)
    expected = _all_positions(item)
    before = runtime.get_runtime(scene, item).field
    path = tmp_path / "field.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    # load_post dropped every runtime; a field is resolved again from its stored settings and
    # its saved frame written at once (the file shows grass before any frame change)
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    assert all(rt.field is not before for rt in runtime.REGISTRY.fields.values())
    assert runtime.get_runtime(scene, item).frame == 12
    for name, pos in expected.items():
        np.testing.assert_allclose(_all_positions(item)[name], pos, atol=1e-6, err_msg=name)
    scene.frame_set(3)  # somewhere else first, so frame 12 really is recomputed
    scene.frame_set(12)
    assert runtime.get_runtime(scene, item) is not None  # rebuilt from the stored parameters
    got = _all_positions(item)
    assert got.keys() == expected.keys()
    for name, pos in expected.items():
        np.testing.assert_allclose(got[name], pos, atol=1e-6, err_msg=name)


def test_a_live_field_saves_its_settings_not_its_slot_meshes(bridge, tmp_path):
    """Issue: a 12.8 m field of 32,768 blades made a 42 MB .blend. A live field is saved as its
    settings, ground and materials; its slots are empty in the file and filled again after the
    save and on load, showing the same frame."""
    _, runtime = bridge
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}  # the first click: 12.8 m, 32,768 blades
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(9)
    expected = _all_positions(item)
    slot_vertices = sum(len(p) for p in expected.values())
    assert slot_vertices > 300_000  # tens of MB of geometry in memory
    path = tmp_path / "lawn.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))  # uncompressed, as Blender saves by default
    # (what is saved: 0.33 MB on Blender 5.2; 2.1 MB on 4.5, which writes the field's node trees,
    # the materials' and the heads', 1.4 MB of it, larger; the slot meshes would be tens of MB)
    assert path.stat().st_size < 3_000_000, path.stat().st_size
    for name, pos in _all_positions(item).items():  # still drawn after the save
        np.testing.assert_array_equal(pos, expected[name], err_msg=name)
    item = _reopened(path, expected)


def test_a_file_saved_with_empty_slot_objects_opens_with_its_grass_and_saves_small(bridge, tmp_path):
    """Files of 0.9 and earlier hold a live field's slot objects with empty meshes (emptied for the
    save). Opened, they show the saved frame's grass; saved again, the slots are left out (they
    are runtime data now: Blender's autosave and quit.blend, which run no save handler, held every
    slot mesh, issue #37)."""
    owned, _ = bridge
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(9)
    expected = _all_positions(item)
    for obj in _owned(item, "blades") + _owned(item, "cards"):  # as the earlier versions saved them
        obj.is_runtime_data = obj.data.is_runtime_data = False
        obj.data.clear_geometry()
    old = tmp_path / "old.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(old), compress=True)
    item = _reopened(old, expected)
    again = tmp_path / "again.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(again), compress=True)
    assert again.stat().st_size < 1_000_000
    assert {o.name for o in owned.slot_objects(item, "blades").values()} <= {o.name for o in bpy.data.objects}
    bpy.ops.wm.open_mainfile(filepath=str(again))
    item = bpy.context.scene.windgrass.fields[0]
    assert bpy.context.scene.frame_current == 9
    assert _all_positions(item).keys() == expected.keys()


def test_a_field_saved_with_older_materials_gets_new_ones(bridge, tmp_path):
    """Materials built by an older version's node trees (here: a canopy without the sward's
    profile) are replaced when the reopened field is rebuilt; current ones are kept."""
    from windgrass.grass_addon.bridge import materials

    owned, _ = bridge
    scene, item = _add_field()
    canopy = owned.registered(item)[owned.ROLE_CANOPY_MATERIAL]
    blade = owned.registered(item)[owned.ROLE_BLADE_MATERIAL].name
    canopy.node_tree.nodes.remove(canopy.node_tree.nodes[materials.NODE_SWARD_PROFILE])
    del canopy["wg_version"]
    path = tmp_path / "old.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    assert bpy.ops.windgrass.field_rebuild() == {"FINISHED"}
    new = owned.registered(item)[owned.ROLE_CANOPY_MATERIAL]
    assert materials.is_current(new) and materials.NODE_SWARD_PROFILE in new.node_tree.nodes
    assert owned.ground_object(item).data.materials[1] == new
    assert owned.registered(item)[owned.ROLE_BLADE_MATERIAL].name == blade  # kept
    scene.frame_set(2)


def _counts():
    return {kind: len(getattr(bpy.data, kind)) for kind in ("objects", "meshes", "materials", "images", "collections")}


def test_remove_leaves_no_orphans_and_undo_restores(bridge):
    _, runtime = bridge
    before = _counts()
    scene, item = _add_field()
    added = _counts()
    # its images: the card atlas, the gust waves, the far canopy's trails and the meadow's patches
    assert added["objects"] > before["objects"] and added["images"] == before["images"] + 4
    bpy.ops.ed.undo_push(message="field added")
    assert bpy.ops.windgrass.field_remove("EXEC_DEFAULT") == {"FINISHED"}
    assert _counts() == before
    assert not [m for m in bpy.data.meshes if m.users == 0]
    assert not runtime.REGISTRY.fields
    # Undo works headless once an undo step exists: the field comes back with its objects.
    bpy.ops.ed.undo_push(message="field removed")
    assert bpy.ops.ed.undo() == {"FINISHED"}
    scene = bpy.context.scene
    assert len(scene.windgrass.fields) == 1 and _counts() == added
    item = scene.windgrass.fields[0]
    scene.frame_set(5)  # the runtime drives the restored objects again
    assert runtime.get_runtime(scene, item).frame == 5


def test_deleting_a_slot_by_hand_does_not_break_frame_changes(bridge, capsys):
    _, runtime = bridge
    # 6 blocks of 16 x 16 cells (512 blades, 6144 vertices), 4 per object: 2 blade objects
    scene, item = _add_field(blocks_x=3, cells_per_block=16)
    blades = _owned(item, "blades")
    assert len(blades) == 2
    bpy.data.objects.remove(blades[0], do_unlink=True)
    survivor = blades[1]
    before = _positions(survivor).copy()
    scene.frame_set(2)
    scene.frame_set(25)  # must not raise
    assert not np.array_equal(before, _positions(survivor))  # the other slots still move
    bpy.data.collections.remove(item.collection)
    scene.frame_set(26)  # the whole collection gone: still no exception
    assert "Windgrass" in capsys.readouterr().out


def _far_field_frames(bridge, tmp_path, gust_waves: float, frames=(1, 13)):
    """A 51 m field seen from 6 m up, the cards ending 3 m out so the far canopy fills the image's
    lower half; rendered at 96x54 (Cycles, 4 samples) at ``frames``: their rows 55-95 % down."""
    import stage
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties

    _, runtime = bridge
    params = schema.defaults().replace({
        "field.blocks_x": 32, "field.blocks_y": 32, "lod.blade_near": 0.5, "lod.blade_far": 1.0,
        "lod.card_near": 2.0, "lod.card_far": 3.0, "wind.type": "calm", "wind.speed": 6.0, "wind.direction": 0.0,
        "wind.gust_waves": gust_waves, "wind.gust_wave_size": 4.0, "camera.mode": "fixed",
        "camera.position": [0.0, -24.0, 6.0], "camera.target": [0.0, 0.0, 0.0], "render.resolution_x": 96,
        "render.resolution_y": 54, "render.samples": 4})
    scene = bpy.context.scene
    stage.setup_stage(scene, params)
    scene.camera.animation_data_clear()
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    out = []
    for frame in frames:
        scene.frame_set(frame)
        scene.render.filepath = str(tmp_path / f"gust{gust_waves}_{frame}.png")
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(scene.render.filepath)
        w, h = image.size
        pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)[::-1, :, :3]
        bpy.data.images.remove(image)
        out.append(pixels[int(0.55 * h):int(0.95 * h)].mean(axis=2))
    return out


def test_gust_waves_run_across_the_far_field(bridge, tmp_path):
    """Issue: the far field was a still plane while the near grass swayed. With gust waves the far
    canopy brightens and darkens where they pass, and they move: half a second later its pixels
    changed several times more than in calm air (where only the render's noise and the near cards
    change), and a frame's far field shows patches (its spread is larger than calm's)."""
    calm = _far_field_frames(bridge, tmp_path, 0.0)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    gusty = _far_field_frames(bridge, tmp_path, 0.8)
    change_calm = float(np.abs(calm[1] - calm[0]).mean())
    change_gusty = float(np.abs(gusty[1] - gusty[0]).mean())
    assert change_gusty > 4.0 * change_calm + 0.002, (change_gusty, change_calm)
    assert float(gusty[0].std()) > 1.5 * float(calm[0].std()), (gusty[0].std(), calm[0].std())
