"""Live edits in Blender: a setting edited on a built field draws, in Blender's evaluated meshes, what a
field built fresh with the edited settings draws; an edit in place (``edit_parts``: the wind, the
solver, LOD distances, colours) makes no block again and leaves the objects as they are."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from mathutils import Vector

SMALL = {"field.blocks_x": 4, "field.blocks_y": 4, "field.cells_per_block": 8, "field.blades_per_cell": 2,
         "wind.speed": 6.0, "wind.gust_waves": 0.6, "lod.blade_near": 1.0, "lod.blade_far": 2.0,
         "lod.card_near": 2.5, "lod.card_far": 8.0}
FRAME = 14

# (setting, how to edit it on the field item, its value in the settings)
EDITS = [
    ("wind.speed", lambda it: setattr(it.wind, "speed", 9.0), {"wind.speed": 9.0}),
    ("wind.direction", lambda it: setattr(it.wind, "direction", math.radians(140.0)), {"wind.direction": 140.0}),
    ("wind.turbulence", lambda it: setattr(it.wind, "turbulence", 0.9), {"wind.turbulence": 0.9}),
    ("wind.gust_waves", lambda it: setattr(it.wind, "gust_waves", 0.2), {"wind.gust_waves": 0.2}),
    ("blade.air_damping", lambda it: setattr(it.blade, "air_damping", 0.9), {"blade.air_damping": 0.9}),
    ("blade.twist_stiffness", lambda it: setattr(it.blade, "twist_stiffness", 0.02),
     {"blade.twist_stiffness": 0.02}),
    ("interaction.recovery", lambda it: setattr(it.interaction, "recovery", 0.5), {"interaction.recovery": 0.5}),
    ("lod.card_near", lambda it: setattr(it.lod, "card_near", 3.5), {"lod.card_near": 3.5}),
    ("lod.blade_far", lambda it: setattr(it.lod, "blade_far", 2.4), {"lod.blade_far": 2.4}),
    ("lod.card_width", lambda it: setattr(it.lod, "card_width", 1.4), {"lod.card_width": 1.4}),
    ("render.haze_distance", lambda it: setattr(it.render, "haze_distance", 300.0), {"render.haze_distance": 300.0}),
    ("field.blades_per_cell", lambda it: setattr(it.field, "blades_per_cell", 3), {"field.blades_per_cell": 3}),
    ("blade.root_stiffness", lambda it: setattr(it.blade, "root_stiffness", 0.004), {"blade.root_stiffness": 0.004}),
]
IN_PLACE = {"wind.speed", "wind.direction", "wind.turbulence", "wind.gust_waves", "blade.air_damping",
            "blade.twist_stiffness", "interaction.recovery", "lod.card_near", "lod.blade_far", "lod.card_width",
            "render.haze_distance"}

# (LOD distances and the haze show in the materials and the cards' fade; the recovery only where grass was trampled)
NOT_IN_THE_MESHES = {"lod.card_near", "lod.card_width", "render.haze_distance", "lod.blade_far", "interaction.recovery"}


def _camera_scene():
    """An empty scene with a camera looking over the field."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (-1.3, -1.0, 0.7)
    cam.rotation_euler = (Vector((0.4, 0.3, 0.1)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    return scene


def _build(params):
    from windgrass.grass_addon.bridge import properties, runtime

    scene = _camera_scene()
    runtime.build_field(scene, properties.add_field(scene, params))
    scene.frame_set(FRAME)
    return scene, scene.windgrass.fields[0]


def _drawn(drawn, item):
    return drawn(item, "blades"), drawn(item, "cards")


@pytest.mark.parametrize("name,edit,values", EDITS, ids=[e[0] for e in EDITS])
def test_an_edit_draws_what_a_fresh_build_draws(with_bridge, drawn, name, edit, values):
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace(SMALL)
    scene, item = _build(base)
    before = _drawn(drawn, item)
    engine = REGISTRY.live(key_of(scene, item)).field
    made = engine.cache.made
    objects = {o.name for o in item.collection.objects}
    edit(item)
    assert runtime.field_error(scene, item) is None
    scene.frame_set(FRAME)
    after = _drawn(drawn, item)
    live = REGISTRY.live(key_of(scene, item))
    if name in IN_PLACE:
        assert live.field is engine and engine.cache.made == made, f"{name}: the field's blocks were made again"
        assert {o.name for o in item.collection.objects} == objects
    want_scene, want_item = _build(base.replace(values))
    want = _drawn(drawn, want_item)
    for got, fresh in zip(after, want):
        assert got.shape == fresh.shape
        np.testing.assert_array_equal(got, fresh, err_msg=name)
    if name not in NOT_IN_THE_MESHES:
        assert not np.array_equal(after[0], before[0]), f"{name}: the edit changed nothing drawn"


def test_an_edit_in_place_and_its_undo(with_bridge, drawn):
    """Ctrl+Z after a wind edit draws the grass of the setting before it."""
    from windgrass.grass_addon import schema

    scene, item = _build(schema.defaults().replace(SMALL))
    before = drawn(item, "blades")
    bpy.ops.ed.undo_push(message="built")
    item.wind.speed = 11.0
    bpy.ops.ed.undo_push(message="wind")
    scene.frame_set(FRAME)
    assert not np.array_equal(drawn(item, "blades"), before)
    bpy.ops.ed.undo()
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    assert item.wind.speed == pytest.approx(6.0)
    scene.frame_set(FRAME)
    np.testing.assert_array_equal(drawn(item, "blades"), before)


def test_a_layout_edit_in_the_ui_builds_in_the_background(with_bridge, drawn):
    """A density edit as the UI applies it (deferred, then the edits' timer): the timer returns
    while the new engine is still being made on a thread, the grass is hidden and the panel's
    figure says how far the build is; a second edit made meanwhile waits for it (one build at a
    time) and the field ends drawing what a fresh build of the last settings draws."""
    import threading
    import time

    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import edits, runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.blocks_x": 8, "field.blocks_y": 8})
    scene, item = _build(base)
    live = REGISTRY.live(key_of(scene, item))

    def edit_in_the_ui(value):
        REGISTRY.batch_depth += 1  # (the property's own update would apply it at once in a script)
        item.field.blades_per_cell = value
        REGISTRY.batch_depth -= 1
        edits.mark_dirty(scene, item, defer=True)
        time.sleep(edits.EDIT_SETTLE_S + 0.01)
        edits.flush_pending()

    edit_in_the_ui(3)
    first = live.building
    assert first is not None and not first.done.is_set(), "the timer waited for the build"
    assert runtime.building_percent(scene, item) is not None
    assert not np.any(drawn(item, "blades")), "the grass of the old settings was left showing"
    running = not first.done.is_set()
    edit_in_the_ui(4)
    if running:  # (a build still running is waited for: no second thread beside it)
        assert live.building is first or first.done.is_set()
    assert sum(t.name.startswith("windgrass build") and t.is_alive() for t in threading.enumerate()) <= 1
    while live.building is not None:
        live.building.wait()
        edits.poll_builds()
    assert runtime.field_error(scene, item) is None and runtime.building_percent(scene, item) is None
    scene.frame_set(FRAME)
    got = _drawn(drawn, item)
    _, want_item = _build(base.replace({"field.blades_per_cell": 4}))
    for a, b in zip(got, _drawn(drawn, want_item)):
        np.testing.assert_array_equal(a, b)


def test_an_edit_back_while_a_build_runs_drops_it(with_bridge, drawn):
    """A density edit in the UI starts a background build; the artist puts the density back
    before it is done (Ctrl+Z, or the slider back): the field draws its first settings, and the
    build for the abandoned ones is dropped once it ends (nothing waits for it, no timer polls on)."""
    import time

    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import edits, runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.blocks_x": 12, "field.blocks_y": 12})
    scene, item = _build(base)
    before = _drawn(drawn, item)
    live = REGISTRY.live(key_of(scene, item))

    def edit_in_the_ui(value):
        REGISTRY.batch_depth += 1
        item.field.blades_per_cell = value
        REGISTRY.batch_depth -= 1
        edits.mark_dirty(scene, item, defer=True)
        time.sleep(edits.EDIT_SETTLE_S + 0.01)
        edits.flush_pending()

    edit_in_the_ui(3)
    job = live.building
    assert job is not None
    REGISTRY.batch_depth += 1
    item.field.blades_per_cell = 2  # (back as it was, applied as a script's edit: at once)
    REGISTRY.batch_depth -= 1
    edits.mark_dirty(scene, item, defer=False)
    job.wait()
    assert edits.poll_builds() is None and live.building is None
    assert runtime.field_error(scene, item) is None
    scene.frame_set(FRAME)
    for a, b in zip(_drawn(drawn, item), before):
        np.testing.assert_array_equal(a, b)


def _edit_in_the_ui(scene, item, setter):
    """An edit as the UI applies it: the property set (its update deferred), then the edits'
    timer once they settle."""
    import time

    from windgrass.grass_addon.bridge import edits
    from windgrass.grass_addon.bridge.registry import REGISTRY

    REGISTRY.batch_depth += 1  # (the property's own update would apply it at once in a script)
    setter(item)
    REGISTRY.batch_depth -= 1
    edits.mark_dirty(scene, item, defer=True)
    time.sleep(edits.EDIT_SETTLE_S + 0.01)
    edits.flush_pending()




def test_a_wind_drag_in_the_ui_runs_on_a_thread_and_follows(with_bridge, drawn):
    """Issue #58: a wind edit in the UI simulates its new run on a thread: when the edits' timer
    returns, the grass of the settings before is still drawn (not hidden, not the new run); an
    edit made while it runs (a slider dragged on) is not queued beside it, and the field ends
    drawing what a fresh build of the last value draws."""
    import threading

    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.blocks_x": 8, "field.blocks_y": 8})
    scene, item = _build(base)
    before = drawn(item, "blades")
    live = REGISTRY.live(key_of(scene, item))
    _edit_in_the_ui(scene, item, lambda it: setattr(it.wind, "speed", 9.0))
    assert live.building is not None, "the new run was made in the window's thread"
    assert runtime.background_work(scene, item).startswith("Simulating the new settings: ")  # (the panel's line)
    now = drawn(item, "blades")
    assert np.any(now) and np.array_equal(now, before), "the grass was hidden or changed before its run was done"
    _edit_in_the_ui(scene, item, lambda it: setattr(it.wind, "speed", 11.0))
    assert sum(t.name.startswith("windgrass build") and t.is_alive() for t in threading.enumerate()) <= 1
    runtime.shown_when_done(scene, item)
    assert runtime.field_error(scene, item) is None
    scene.frame_set(FRAME)
    got = _drawn(drawn, item)
    _, want_item = _build(base.replace({"wind.speed": 11.0}))
    for a, b in zip(got, _drawn(drawn, want_item)):
        np.testing.assert_array_equal(a, b)


def _first_look_drawn(job, item, drawn, after: str):
    """The blades drawn once the edits' timer wrote ``job``'s first look, which must come before
    the job is done (``after``: what it would have come after)."""
    import time

    from windgrass.grass_addon.bridge import edits

    waited = time.monotonic()
    while job.first_look is None and time.monotonic() - waited < 30.0:
        time.sleep(0.002)
    assert job.first_look is not None and not job.done.is_set(), f"the first look came after {after}"
    edits.poll_builds()
    return drawn(item, "blades")


def _windier_first_look(drawn):
    """A small field in a 3 m/s wind (a warm-up of 20 s) edited to 12 m/s in the UI, its first look
    drawn and the panel saying so: (settings before, scene, field, its record, the blades drawn
    before the edit, the blades of the first look)."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.blocks_x": 12, "field.blocks_y": 12, "wind.speed": 3.0,
                                      "simulation.preroll": 20.0, "simulation.epoch": 20.0})
    scene, item = _build(base)
    before = drawn(item, "blades")
    live = REGISTRY.live(key_of(scene, item))
    _edit_in_the_ui(scene, item, lambda it: setattr(it.wind, "speed", 12.0))
    job = live.building
    assert job is not None and job.looks_first
    first = _first_look_drawn(job, item, drawn, "the run")
    assert runtime.background_work(scene, item).endswith(", a first look shown")  # (the panel's line)
    return base, scene, item, live, before, first


def test_a_wind_edit_in_the_ui_shows_a_first_look_at_once_then_its_run(with_bridge, drawn):
    """Issue #58: a wind edit in the UI shows at once: before its new run is done (a warm-up of
    20 s here), the field draws a first look of the new wind (0.75 s of it simulated from
    rest): its blades lean as far as the run's own do, within a fifth of how far the grass moved
    (a stronger wind lowers them); the run's frame, the bits of a fresh build, replaces it."""
    from windgrass.grass_addon.bridge import runtime

    base, scene, item, live, before, first = _windier_first_look(drawn)
    job = live.building
    assert not job.done.is_set() or live.engine is job.base  # (what was drawn is the first look, not the run)
    runtime.shown_when_done(scene, item)
    assert runtime.field_error(scene, item) is None
    exact = drawn(item, "blades")
    _, want_item = _build(base.replace({"wind.speed": 12.0}))
    np.testing.assert_array_equal(exact, drawn(want_item, "blades"))
    height = {name: float(np.mean(v[:, 2])) for name, v in (("before", before), ("first", first), ("run", exact))}
    moved = height["before"] - height["run"]
    assert moved > 0.01, height  # (a 12 m/s wind bends the blades down: it shows)
    assert abs(height["first"] - height["run"]) < 0.2 * moved, height


def test_the_panel_says_no_first_look_once_the_grass_before_the_edit_is_drawn_over_it(with_bridge, drawn):
    """A wind slider dragged on while its first look is drawn: the next step of the drag draws the
    grass of the settings before over the first look (its run goes on), so the panel's line no
    longer says a first look is shown; the field ends drawing a fresh build of the last value."""
    from windgrass.grass_addon.bridge import runtime

    base, scene, item, live, before, _ = _windier_first_look(drawn)
    job = live.building
    _edit_in_the_ui(scene, item, lambda it: setattr(it.wind, "speed", 11.0))  # (the drag goes on)
    assert live.building is job and not job.done.is_set()  # (the first run still going, 20 s of warm-up)
    np.testing.assert_array_equal(drawn(item, "blades"), before)  # (the grass before, over the first look)
    line = runtime.background_work(scene, item)
    assert line is not None and line.startswith("Simulating") and "first look" not in line, line
    runtime.shown_when_done(scene, item)
    got = drawn(item, "blades")
    _, want_item = _build(base.replace({"wind.speed": 11.0}))
    np.testing.assert_array_equal(got, drawn(want_item, "blades"))


def test_a_density_edit_in_the_ui_shows_the_new_fields_first_look_before_its_first_frame(with_bridge, drawn):
    """Issue #58: a density edit in the UI hides the grass while the new field is made; once its
    blocks are, and before its first frame's warm-up (20 s here) is done, the field draws the new
    field's first look: as many blades as its own frame then draws, leaning as far (mean height
    within a tenth); its frame, a fresh build's bits, replaces it."""

    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.blocks_x": 12, "field.blocks_y": 12, "wind.speed": 8.0,
                                      "simulation.preroll": 20.0, "simulation.epoch": 20.0})
    scene, item = _build(base)
    live = REGISTRY.live(key_of(scene, item))
    _edit_in_the_ui(scene, item, lambda it: setattr(it.field, "blades_per_cell", 4))
    job = live.building
    assert job is not None and job.base is None and job.looks_first
    assert not np.any(drawn(item, "blades")), "the grass of the old settings was left showing"
    first = _first_look_drawn(job, item, drawn, "the field")
    runtime.shown_when_done(scene, item)
    assert runtime.field_error(scene, item) is None
    exact = drawn(item, "blades")
    _, want_item = _build(base.replace({"field.blades_per_cell": 4}))
    np.testing.assert_array_equal(exact, drawn(want_item, "blades"))
    points = [len(np.unique(v.round(6), axis=0)) for v in (first, exact)]  # (what shows nothing is one point)
    assert points[0] > 1000 and abs(points[0] - points[1]) <= 0.005 * points[1], points
    heights = [float(np.mean(v[:, 2])) for v in (first, exact)]
    assert abs(heights[0] - heights[1]) < 0.1 * heights[1], heights


def test_a_field_added_from_the_menu_is_built_in_the_background(with_bridge, drawn):
    """Issue #58: Add Grass Field from the menu (``build_in_background``, the operator's invoke in
    the UI) makes the field's objects and returns before its engine is made: nothing of it is
    drawn yet; the timer draws its first look before its frame (the blocks made, the warm-up not
    simulated), then the frame a field added by a script draws, bit for bit."""

    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    params = schema.defaults().replace({**SMALL, "field.blocks_x": 12, "field.blocks_y": 12, "wind.speed": 8.0,
                                        "simulation.preroll": 20.0, "simulation.epoch": 20.0})
    _, want_item = _build(params)
    want = drawn(want_item, "blades")
    scene = _camera_scene()
    scene.frame_set(FRAME)
    item = properties.add_field(scene, params)
    runtime.build_in_background(scene, item)
    job = REGISTRY.live(key_of(scene, item)).building
    assert job is not None and not job.done.is_set(), "the engine was made before Add returned"
    assert item.collection is not None and not np.any(drawn(item, "blades"))
    first = _first_look_drawn(job, item, drawn, "the field")
    assert len(np.unique(first.round(6), axis=0)) > 1000
    runtime.shown_when_done(scene, item)
    assert runtime.field_error(scene, item) is None
    np.testing.assert_array_equal(drawn(item, "blades"), want)


def _slot_data(item) -> list:
    """Every slot mesh of a field as Blender holds it, in slot order: its positions and each of
    its float attributes (the blades' colours and marks, the cards' opacity: UV maps and point
    attributes), by name."""
    out = []
    for role in ("blades", "cards"):
        objects = sorted((o for o in item.collection.objects if o.get("wg_role") == role and o.type == "MESH"),
                         key=lambda o: int(o.get("wg_slot", -1)))
        for obj in objects:
            mesh, data = obj.data, {}
            for attribute in mesh.attributes:
                width = {"FLOAT": 1, "FLOAT2": 2, "FLOAT_VECTOR": 3}.get(attribute.data_type)
                if width is None or attribute.name.startswith("."):
                    continue
                values = np.empty(len(attribute.data) * width, np.float32)
                attribute.data.foreach_get("value" if width == 1 else "vector", values)
                data[attribute.name] = values
            out.append((role, int(obj.get("wg_slot", -1)), data))
    return out


def test_a_field_added_from_the_menu_keeps_what_its_first_look_wrote_of_each_block(with_bridge, drawn):
    """Issue #58: the slot pools a new field's first look was written through go to its engine,
    so its first frame writes the positions and not every block's colours again (the window's
    thread held less); what each slot then holds, positions and every float attribute, is what a
    field added by a script holds. A frame written over the first look before the engine is
    done (the grass hidden meanwhile) hands nothing on, and the slots are again a script's."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    params = schema.defaults().replace({**SMALL, "field.blocks_x": 12, "field.blocks_y": 12, "wind.speed": 8.0,
                                        "simulation.preroll": 20.0, "simulation.epoch": 20.0})
    for frame_between in (False, True):
        want_scene, want_item = _build(params)
        if frame_between:
            want_scene.frame_set(FRAME + 1)
        want = _slot_data(want_item)
        scene = _camera_scene()
        scene.frame_set(FRAME)
        item = properties.add_field(scene, params)
        runtime.build_in_background(scene, item)
        live = REGISTRY.live(key_of(scene, item))
        job = live.building
        _first_look_drawn(job, item, drawn, "the field")
        pools = job.look_pools
        assert pools is not None and set(pools) == {"blades", "cards"}
        if frame_between:
            scene.frame_set(FRAME + 1)  # (the build still running: the grass hidden, the first look gone)
            assert live.building is not job or job.look_pools is None
        runtime.shown_when_done(scene, item)
        assert runtime.field_error(scene, item) is None
        if not frame_between:
            assert live.engine.pools is pools
        got = _slot_data(item)
        assert [(r, i, sorted(d)) for r, i, d in got] == [(r, i, sorted(d)) for r, i, d in want]
        for (role, index, mine), (_, _, theirs) in zip(got, want):
            for name in mine:
                np.testing.assert_array_equal(mine[name], theirs[name], err_msg=f"{role} {index} {name}")


def _look_drawn(item):
    """What a field's materials and ground show of its look: the evaluated ground mesh's vertices,
    the card atlas's pixels and the far canopy's curves (the sward's colours, depth and grain)."""
    from windgrass.grass_addon.bridge import owned

    depsgraph = bpy.context.evaluated_depsgraph_get()
    ground = owned.ground_object(item).evaluated_get(depsgraph).data
    co = np.empty(len(ground.vertices) * 3, np.float32)
    ground.vertices.foreach_get("co", co)
    reg = owned.registered(item)
    image = reg[owned.ROLE_CARD_IMAGE]
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    curves = [[tuple(p.location) for c in node.mapping.curves for p in c.points]
              for node in sorted(reg[owned.ROLE_CANOPY_MATERIAL].node_tree.nodes, key=lambda n: n.name)
              if hasattr(node, "mapping") and hasattr(node.mapping, "curves")]
    return co, pixels, curves


def test_a_density_edit_in_the_ui_works_its_look_out_on_a_thread(with_bridge):
    """Issue #58: a density edit in the UI rebuilds the field's objects in the edit, but the far
    grass's look (seconds of work: the sward's colours, the card atlas, the canopy's heights) is
    worked out on a thread: the edit leaves the materials as they were, and once it is ready the
    timer writes it: the ground, the card atlas and the canopy's curves are then those a fresh
    build of the settings shows."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.seed": 4057, "lod.card_width": 1.13})  # (a look no test asked)
    scene, item = _build(base)
    before = _look_drawn(item)
    live = REGISTRY.live(key_of(scene, item))
    _edit_in_the_ui(scene, item, lambda it: setattr(it.field, "blades_per_cell", 5))
    assert live.look_waiting, "the look was worked out in the window's thread"
    assert runtime.background_work(scene, item).startswith("Building the field for its new settings: ")
    np.testing.assert_array_equal(_look_drawn(item)[1], before[1])  # (the atlas as it was, meanwhile)
    runtime.shown_when_done(scene, item)
    got = _look_drawn(item)
    _, want_item = _build(base.replace({"field.blades_per_cell": 5}))
    want = _look_drawn(want_item)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]
    assert not np.array_equal(got[1], before[1]), "more blades a cell, and the cards look the same"


def test_a_render_right_after_an_edit_in_the_ui_shows_its_look(with_bridge):
    """Issue #58: F12 pressed while an edit's look is still worked out on a thread: Blender's
    render_pre handler writes it first (the render never shows the look of the settings before)."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import handlers
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    base = schema.defaults().replace({**SMALL, "field.seed": 4061, "lod.card_width": 1.17})  # (a look no test asked)
    scene, item = _build(base)
    live = REGISTRY.live(key_of(scene, item))
    _edit_in_the_ui(scene, item, lambda it: setattr(it.blade, "root_stiffness", 0.0011))
    assert live.look_waiting
    handlers.on_render_pre(scene)
    try:
        assert not live.look_waiting
        got = _look_drawn(item)
    finally:
        handlers.on_render_post(scene)
    _, want_item = _build(base.replace({"blade.root_stiffness": 0.0011}))
    want = _look_drawn(want_item)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]


def test_a_look_edit_in_the_ui_says_its_look_is_worked_out(with_bridge):
    """The sun's elevation (a look setting: the far grass's colours) edited in the UI keeps the
    field's run; the panel's line says the far grass's look is worked out meanwhile, and nothing
    once it is written."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import runtime

    base = schema.defaults().replace({**SMALL, "field.seed": 4073})  # (a look no test asked)
    scene, item = _build(base)
    assert runtime.background_work(scene, item) is None
    _edit_in_the_ui(scene, item, lambda it: setattr(it.render, "sun_elevation", 23.0))
    assert runtime.background_work(scene, item) == "Working out the far grass's look for the new settings"
    runtime.shown_when_done(scene, item)
    assert runtime.background_work(scene, item) is None


def test_a_stiffness_edit_in_a_script_lifts_the_far_canopy_as_a_fresh_build_does(with_bridge):
    """A root stiffness edit keeps the field's objects (their topology holds) but changes how far
    the blades droop at rest, so the far canopy's height over the ground: the ground mesh, the card
    atlas and the canopy's curves are those a fresh build of the settings shows."""
    from windgrass.grass_addon import schema

    base = schema.defaults().replace({**SMALL, "field.seed": 4079})
    scene, item = _build(base)
    objects = {o.name for o in item.collection.objects}
    before = _look_drawn(item)
    item.blade.root_stiffness = 0.0002  # (a script's edit: applied at once)
    got = _look_drawn(item)
    assert {o.name for o in item.collection.objects} == objects
    _, want_item = _build(base.replace({"blade.root_stiffness": 0.0002}))
    want = _look_drawn(want_item)
    assert not np.array_equal(want[0], before[0]), "the canopy stands as high for blades this soft"
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2]


def _canopy_reach(item) -> float:
    """Where the far canopy the field's material draws has fully taken over from the cards (m
    from the eye: the Map Range of eq 10's d_s2 in its material)."""
    from windgrass.grass_addon.bridge import materials, owned

    kt = owned.recorded(item, owned.ROLE_CANOPY_MATERIAL).node_tree.nodes[materials.NODE_KT]
    return float(next(s for s in kt.inputs if s.name == "From Max" and s.enabled).default_value)


def _across(scene):
    """``scene`` with its camera at eye level, looking across the field (it sees most blocks)."""
    cam = scene.camera
    cam.location = (0.0, -20.0, 1.2)
    cam.rotation_euler = (Vector((0.0, 10.0, 0.0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    return scene


def _farthest_card(item, drawn, eye) -> float:
    cards = drawn(item, "cards")
    cards = cards[np.linalg.norm(cards, axis=1) > 1e-6]  # (positions that show nothing: at the origin)
    return float(np.linalg.norm(cards[:, :2] - np.asarray(eye)[:2], axis=1).max())


def test_a_field_added_from_the_menu_shows_its_near_blocks_first_and_its_canopy_from_where_they_end(
        with_bridge, drawn):
    """Issue #58: a new field's first look draws its detail only as far as its nearest blocks
    reach (``FIRST_LOOK_BLOCKS``: those it makes first, so it shows in half the time); the far
    canopy then takes over where that look's cards end, not at the field's card range, so no bare
    ground lies between; once the field is done its cards and canopy reach as far as a field
    added by a script."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime
    from windgrass.grass_addon.bridge.registry import REGISTRY, key_of

    params = schema.defaults().replace({**SMALL, "field.blocks_x": 60, "field.blocks_y": 60, "lod.card_far": 30.0,
                                        "simulation.preroll": 20.0, "simulation.epoch": 20.0})
    want_scene = _across(_camera_scene())
    want_item = properties.add_field(want_scene, params)
    runtime.build_field(want_scene, want_item)
    want_scene.frame_set(FRAME)
    eye = tuple(want_scene.camera.location)
    want_reach, want_far = _canopy_reach(want_item), _farthest_card(want_item, drawn, eye)
    want_cards = drawn(want_item, "cards")
    scene = _across(_camera_scene())  # (a new file: the field above is gone)
    scene.frame_set(FRAME)
    item = properties.add_field(scene, params)
    runtime.build_in_background(scene, item)
    _first_look_drawn(REGISTRY.live(key_of(scene, item)).building, item, drawn, "the field")
    look_reach, look_far = _canopy_reach(item), _farthest_card(item, drawn, eye)
    assert look_reach < 0.7 * want_reach, (look_reach, want_reach)  # (its detail nearer)
    assert look_far < 0.8 * want_far
    assert look_far >= look_reach, (look_far, look_reach)  # its cards reach where the canopy has taken over
    runtime.shown_when_done(scene, item)
    assert runtime.field_error(scene, item) is None
    assert _canopy_reach(item) == pytest.approx(want_reach, abs=1e-4)
    np.testing.assert_array_equal(drawn(item, "cards"), want_cards)
