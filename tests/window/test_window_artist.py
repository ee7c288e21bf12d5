"""The artist's Blender: the viewport follows the 3D views, renders the scene camera, Solid shading
reads as a meadow, files stay small, Add grows where the artist asks, bakes say what is missing.

The field of these tests: 32 x 32 blocks of 1.6 m (51.2 m square, centred on the origin), LOD
distances by default (blades to 12 m, cards to 40 m). The startup file's camera stands at
(7.4, -6.9, 5.0) looking at the origin.
"""

import math

import numpy as np
from PIL import Image

BLOCKS, BLOCK = 32, 1.6
HALF = BLOCKS * BLOCK / 2
BLADE_FAR = 12.0
FIELD = [{"select": None}, {"op": "windgrass.field_add", "args": {"blocks_x": BLOCKS, "blocks_y": BLOCKS}}]
STARTUP_CAMERA = (7.36, -6.93, 4.96)


def block_of(x, y):
    return int((y + HALF) // BLOCK) * BLOCKS + int((x + HALF) // BLOCK)


def block_distance(block, eye):
    """Distance from ``eye`` to the nearest point of a block's ground rectangle."""
    by, bx = divmod(block, BLOCKS)
    x0, y0 = -HALF + bx * BLOCK, -HALF + by * BLOCK
    dx = max(x0 - eye[0], 0.0, eye[0] - (x0 + BLOCK))
    dy = max(y0 - eye[1], 0.0, eye[1] - (y0 + BLOCK))
    return math.sqrt(dx * dx + dy * dy + eye[2] ** 2)


def test_viewport_follows_each_3d_view_and_renders_follow_the_scene_camera(real_blender):
    """Issue: blocks outside the scene camera's view were bare while the artist orbited. Blades
    grow in front of whichever 3D view looks, in two views at once, and a render (F12) uses the
    scene camera."""
    eye_a, eye_b = (-20.0, 15.0, 1.7), (18.0, 18.0, 1.7)
    capture = ("import bpy\n"
               "shown = bpy.app.driver_namespace.setdefault('wg_render', [])\n"
               "rt = bridge('runtime')\n"
               "def grab(scene, *args):\n"
               "    shown.append([int(b) for b in rt.get_runtime(scene, scene.windgrass.fields[0]).blades.blocks])\n"
               "bpy.app.handlers.render_post.append(grab)\n"
               "scene = bpy.context.scene\n"
               "scene.render.engine = 'CYCLES'\nscene.cycles.samples = 1\nscene.cycles.use_denoising = False\n"
               "scene.render.resolution_x, scene.render.resolution_y = 64, 36\n"
               "result = True")
    steps = [*FIELD,
             {"view": {"look": [list(eye_a), [0.0, 15.0, 0.3]]}}, {"wait": 1.0}, {"probe": "lod"},
             {"view": {"look": [list(eye_b), [18.0, 0.0, 0.3]]}}, {"wait": 1.0}, {"probe": "lod"},
             {"split": "VERTICAL"},
             {"view": {"area": 0, "look": [list(eye_a), [0.0, 15.0, 0.3]]}},
             {"view": {"area": 1, "look": [list(eye_b), [18.0, 0.0, 0.3]]}}, {"wait": 1.0}, {"probe": "lod"},
             {"shot": "two_views"},
             {"python": capture}, {"op": "render.render"}, {"wait": 1.0},
             {"python": "result = bpy.app.driver_namespace['wg_render']"}, {"probe": "lod"},
             {"frame": 1}, {"check": "fields"}]
    run = real_blender.run(steps)
    run.assert_clean()
    a, b, both, after_render = (p["Grass"]["blade_blocks"] for p in run.results("probe"))
    ahead_a, ahead_b = block_of(-17.0, 15.0), block_of(18.0, 15.0)  # 3 m in front of each eye
    assert ahead_a in a and ahead_b not in a
    assert ahead_b in b and ahead_a not in b
    assert all(block_distance(k, eye_a) <= BLADE_FAR + 1e-3 for k in a)  # blades near the view, not the camera
    assert ahead_a in both and ahead_b in both  # two 3D views at once
    rendered = run.results("python")[1][0]
    assert rendered and all(block_distance(k, STARTUP_CAMERA) <= BLADE_FAR + 1e-3 for k in rendered)
    assert ahead_a not in rendered and ahead_b not in rendered  # the render saw the scene camera's grass
    assert ahead_a in after_render and ahead_b in after_render  # and the viewport follows its views again


def test_the_viewport_draws_its_display_amount_and_renders_draw_every_blade(real_blender):
    """Viewport Amount 0.25 (LOD): the 3D view draws a quarter of the blades it drew at 1 (0.15 to
    0.35 of them: each cell's count rounded), in blocks it drew before (the far ones whose cells
    round to none left out); a render (F12) draws as many
    as before, every blade; the LOD panel says how many the viewport draws, and the viewport
    draws as few again after the render."""
    eye = [[-20.0, 15.0, 1.7], [0.0, 15.0, 0.3]]
    capture = ("import bpy\n"
               "shown = bpy.app.driver_namespace.setdefault('wg_drawn', [])\n"
               "rt = bridge('runtime')\n"
               "def grab(scene, *args):\n"
               "    shown.append(rt.get_runtime(scene, scene.windgrass.fields[0]).blades_drawn)\n"
               "bpy.app.handlers.render_post.append(grab)\n"
               "scene = bpy.context.scene\n"
               "scene.render.engine = 'CYCLES'\nscene.cycles.samples = 1\nscene.cycles.use_denoising = False\n"
               "scene.render.resolution_x, scene.render.resolution_y = 64, 36\n"
               "result = True")
    steps = [*FIELD, {"view": {"look": eye}}, {"wait": 1.0}, {"probe": "lod"},
             {"python": capture}, {"op": "render.render"}, {"wait": 1.0},
             {"set": "windgrass.fields[0].lod.viewport_amount", "value": 0.25}, {"wait": 1.5},
             {"view": {"look": eye}}, {"wait": 1.0}, {"probe": "lod"}, {"shot": "quarter"},
             {"op": "render.render"}, {"wait": 1.0}, {"probe": "lod"},
             {"python": "result = bpy.app.driver_namespace['wg_drawn']"}, {"check": "fields"}]
    run = real_blender.run(steps)
    run.assert_clean()
    full, quarter, after = (p["Grass"] for p in run.results("probe"))
    renders = run.results("python")[1]
    assert full["blades_drawn"] > 10000 and 0.15 < quarter["blades_drawn"] / full["blades_drawn"] < 0.35
    assert set(quarter["blade_blocks"]) <= set(full["blade_blocks"])
    assert len(renders) == 2 and renders[0] == renders[1] > 1000  # (the scene camera's view, all of it)
    assert after["blades_drawn"] == quarter["blades_drawn"]


def _grass_pixels(path):
    """Pixels of the 3D view's lower half (the meadow in front of a low view), RGB 0..1."""
    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    h, w, _ = image.shape
    return image[int(0.55 * h):int(0.85 * h), int(0.05 * w):int(0.75 * w)].reshape(-1, 3)


def test_solid_shading_reads_as_a_green_meadow(real_blender):
    """Issue: in Solid mode cards drew as grey shards, the canopy as a grey slab. Seen from inside
    the field, low, the view is green: the meadow's pixels are green, not grey. (Grey has r = g = b;
    the meadow's olive, its cards in the colour of heads and dry tips seen from afar, is a hue of
    92 degrees with green 1.20 times red: 1.203 before the patches' third octave, 1.198 after. The
    bound is 1.15, well clear of grey and of that chance, not the meadow's own figure.)"""
    steps = [*FIELD, {"view": {"look": [[0.0, -10.0, 1.7], [0.0, 5.0, 0.0]]}}, {"shading": "SOLID"}, {"wait": 1.0},
             {"shot": "solid"}, {"probe": "materials"}]
    run = real_blender.run(steps)
    run.assert_clean()
    rgb = _grass_pixels(run.shots / "solid.png")
    r, g, b = rgb.mean(axis=0)
    assert g > 1.15 * r and g > 1.15 * b, (r, g, b)  # green, not grey (grey: r = g = b)
    saturation = (rgb.max(axis=1) - rgb.min(axis=1)) / np.maximum(rgb.max(axis=1), 1e-6)
    assert np.median(saturation) > 0.2


def test_a_saved_lawn_is_small_and_reopens_with_its_grass(real_blender, tmp_path):
    """Issue: a 12.8 m field of 32,768 blades saved 42 MB (uncompressed, Blender's default)."""
    path = "{case}/lawn.blend"
    steps = [{"select": None}, {"op": "windgrass.field_add"}, {"frame": 5}, {"check": "fields"},
             {"save": path}, {"check": "fields"}, {"open": path}, {"wait": 1.0}, {"check": "fields"}]
    run = real_blender.run(steps)
    run.assert_clean()
    size = run.results("save")[0][1]
    assert size < 2_000_000, size
    before, saved, reopened = (check["fields"][0] for check in run.results("check"))
    assert before["vertices_shown"] == saved["vertices_shown"] > 0  # still drawn after the save
    assert reopened["vertices_shown"] == before["vertices_shown"]
    assert reopened["frame_written"] == before["frame_written"] == 6  # the saved frame, at once


AUTOSAVE_ON = """
p = bpy.context.preferences.filepaths
p.use_auto_save_temporary_files = True
p.auto_save_time = 1
"""
AUTOSAVED = """
import glob, os, shutil
found = glob.glob(os.path.join(os.environ["TMPDIR"], "*_autosave.blend"))
if found:
    shutil.copy(found[0], os.path.join(os.environ["TMPDIR"], "recovered.blend"))
    result = os.path.getsize(found[0])
"""


def test_autosave_and_quit_blend_are_as_small_as_a_save_and_recover_the_grass(real_blender):
    """Issue #37: Blender's autosave and quit.blend (written without save handlers) held every slot
    mesh of the field: 103 MB and 279 MB where a save was 12.8 MB. Here Blender autosaves after a
    minute, a compressed Save As is made beside it, the autosave is opened as File > Recover does
    and shows its grass, and File > Quit writes quit.blend."""
    steps = [{"select": None}, {"op": "windgrass.field_add"}, {"frame": 5}, {"check": "fields"},
             {"python": AUTOSAVE_ON}, {"settle": AUTOSAVED, "max": 240}, {"python": AUTOSAVED},
             {"save": "{case}/saved.blend", "args": {"compress": True, "copy": True}},
             {"open": "{case}/recovered.blend"}, {"wait": 1.0}, {"check": "fields"}, {"quit": True}]
    run = real_blender.run(steps)
    run.assert_clean()
    autosave = run.results("python")[-1]
    saved = run.results("save")[0][1]
    quit_blend = run.shots.parent / "quit.blend"
    assert quit_blend.exists(), run.output[-2000:]
    # (the three are compressed; before: 8.2 MB for this 12.8 m field in Blender 5.2, its saves 0.23 MB)
    assert autosave is not None and autosave < 1.2 * saved + 50_000, (autosave, saved)
    assert quit_blend.stat().st_size < 1.2 * saved + 50_000, (quit_blend.stat().st_size, saved)
    before, recovered = (check["fields"][0] for check in run.results("check"))
    assert recovered["vertices_shown"] == before["vertices_shown"] > 0


def test_add_grows_on_flat_ground_unless_asked_for_a_mesh(real_blender):
    """Issue: in the startup file the selected Cube became terrain ("a tuft on a box"), and + in
    the panel with a field's ground selected rooted the new field on that ground."""
    terrains = "result = [f.terrain.name if f.terrain else None for f in bpy.context.scene.windgrass.fields]"
    steps = [{"select": "Cube"}, {"op": "windgrass.field_add"}, {"python": terrains},
             {"select": "Grass ground"},
             {"op": "windgrass.field_add", "args": {"use_selected_mesh": True}, "invoke": True},
             {"op": "windgrass.field_add"}, {"python": terrains},
             {"select": "Cube"}, {"op": "windgrass.field_add", "args": {"use_selected_mesh": True}},
             {"python": terrains}]
    run = real_blender.run(steps)
    run.assert_clean()
    first, second, third = run.results("python")
    assert first == [None]  # the selected Cube stays a cube
    refused = run.results("op")[1]
    assert isinstance(refused, dict) and "belongs to a grass field" in refused["error"]  # a sentence
    assert second == [None, None]  # + with the ground selected: flat ground
    assert third == [None, None, "Cube"]  # asked for: on the mesh


def test_the_plain_add_after_an_add_on_a_mesh_grows_on_flat_ground(real_blender):
    """Issue: after one use of Add > Grass Field on Selected Mesh, Blender reused the operator's
    "On Selected Mesh" for the plain Add > Grass Field entry: with nothing selected it failed
    with "select the mesh first", with a mesh selected it rooted on it."""
    terrains = "result = [f.terrain.name if f.terrain else None for f in bpy.context.scene.windgrass.fields]"
    steps = [{"select": "Cube"},
             {"op": "windgrass.field_add", "args": {"use_selected_mesh": True}, "invoke": True},
             {"select": None}, {"op": "windgrass.field_add", "invoke": True},
             {"select": "Cube"}, {"op": "windgrass.field_add", "invoke": True}, {"python": terrains}]
    run = real_blender.run(steps)
    run.assert_clean()
    ops = run.results("op")
    assert ops[1] == ["FINISHED"] and ops[2] == ["FINISHED"], ops  # (no "select the mesh first")
    assert run.results("python")[-1] == ["Cube", None, None]


def test_bake_without_alembic_says_so_and_leaves_nothing(real_blender):
    """Issue: Debian's Blender has no Alembic: Bake showed a Python traceback and left an empty
    cache folder beside the .blend. Issue #63: it has no USD either, and each format's refusal
    pointed at the other (USD was judged by the version alone); both now say, once and plainly,
    that this Blender bakes neither, and point at a Blender that does."""
    steps = [{"select": None}, {"op": "windgrass.field_add", "args": {"blocks_x": 2, "blocks_y": 2}},
             {"save": "{case}/bake_here.blend"},
             {"op": "windgrass.field_bake", "invoke": True},
             {"op": "windgrass.field_bake", "args": {"format": "usd"}, "invoke": True},
             {"python": "import bpy, os\nresult = [sorted(n for n in os.listdir('{case}') "
                        "if n.startswith('bake_here')), bpy.app.build_options.usd]"}]
    run = real_blender.run(steps)
    run.assert_clean()
    if run.report["alembic"]:
        return  # (a Blender with Alembic bakes: tests/blender/test_bake.py)
    print("this Blender has no Alembic: checking the message instead of a bake")
    listed, usd = run.results("python")[0]
    assert listed == ["bake_here.blend"]  # no bake_here_windgrass folder
    errors = [run.results("op")[i]["error"] for i in (1, 2)]
    for error in errors:
        assert "without Alembic" in error and "Traceback" not in error and error.count(". ") == 0, error
    if not usd:
        assert all("neither Alembic nor USD" in e and "here" not in e.split(";")[-1] for e in errors), errors


PAINTED = """
item = bpy.context.scene.windgrass.fields[0]
n = item.blade.segments
edge = 2.0 * item.field.blocks_x * item.field.cells_per_block * item.field.cell_size / 32  # two of the map's pixels
west = east = 0
for obj in bridge("owned").slot_objects(item, "blades").values():
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.attributes["position"].data.foreach_get("vector", co)
    strips = co.reshape(-1, n + 1, 2, 3)
    drawn = np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0
    roots = strips[drawn, 0].mean(axis=1)
    west += int((roots[:, 0] < -edge).sum())
    east += int((roots[:, 0] > edge).sum())
for obj in bridge("owned").slot_objects(item, "cards").values():  # (seen from afar: cards)
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.attributes["position"].data.foreach_get("vector", co)
    quads = co.reshape(-1, 4, 3)
    centres = quads[np.ptp(quads, axis=1).max(axis=1) > 0].mean(axis=1)
    west += int((centres[:, 0] < -edge).sum())
    east += int((centres[:, 0] > edge).sum())
result = {"error": bridge("runtime").field_error(bpy.context.scene, item), "west": west, "east": east,
          "images": sorted(i.name for i in bpy.data.images if i.source == "GENERATED" and not i.name.startswith("Grass")
                           or i.packed_file is not None and not i.name.startswith("Grass"))}
"""

MASK = """
image = bpy.data.images.new("mask", 32, 32, alpha=False)
pixels = np.ones((32, 32, 4), np.float32)
pixels[:, :16, :3] = 0.0
image.pixels.foreach_set(pixels.ravel())
image.pack()
result = image.name
"""

RENAME = """
bpy.data.images["mask"].name = "paths"
bpy.ops.ed.undo_push(message="rename the image")
result = True
"""


def test_an_image_map_survives_save_reopen_rename_undo_and_redo(real_blender):
    """Issue: a field painted by image:mask lost its image at the save (nothing else used it) and
    was hidden at every reopen; a rename hid it after undo, redo or a reopen. In the window: the
    west half stays bare and the east grown (its blades and cards) through all of it."""
    path = "{case}/mask.blend"
    steps = [{"select": None}, {"op": "windgrass.field_add"}, {"python": MASK},
             {"set": "windgrass.fields[0].paint.density", "value": "image:mask"}, {"frame": 1},
             {"python": PAINTED}, {"save": path}, {"open": path}, {"wait": 1.0}, {"python": PAINTED},
             {"python": RENAME}, {"frame": 1}, {"python": PAINTED}, {"key": "ctrl+z"}, {"wait": 1.0},
             {"python": PAINTED}, {"key": "ctrl+shift+z"}, {"wait": 1.0}, {"python": PAINTED},
             {"save": path}, {"open": path}, {"wait": 1.0}, {"python": PAINTED}]
    run = real_blender.run(steps)
    run.assert_clean()
    probes = [r for r in run.results("python") if isinstance(r, dict)]
    assert len(probes) == 6
    for probe in probes:
        assert probe["error"] is None and probe["west"] == 0 and probe["east"] > 100, probe
    assert probes[1]["images"] == ["mask"] and probes[-1]["images"] == ["paths"]


TERRAIN = """
bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=20, size=6.0)
terrain = bpy.context.active_object
terrain.name = "Terrain"
group = terrain.vertex_groups.new(name="meadow")
group.add([v.index for v in terrain.data.vertices if v.co.x > 0.0], 1.0, "REPLACE")
# a weight near 0 on the west half: Blender 5.2 draws 0 (and vertices outside the group) black
group.add([v.index for v in terrain.data.vertices if v.co.x <= 0.0], 0.05, "REPLACE")
result = terrain.name
"""

HIDDEN = """
item = bpy.context.scene.windgrass.fields[0]
objects = bridge("owned").field_objects(item)
result = {"hidden": sorted({o.hide_get() for o in objects}), "count": len(objects),
          "render_hidden": any(o.hide_render for o in objects)}
"""


def _blue_red(path):
    """(share of blue pixels, share of red pixels) of a screenshot: Weight Paint draws weight 0
    blue and weight 1 red; grass is green."""
    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return float(np.mean((b > 1.5 * r) & (b > 1.5 * g) & (b > 80))), float(np.mean((r > 1.5 * g) & (r > 1.5 * b)
                                                                                  & (r > 80)))


def test_weight_painting_the_terrain_shows_the_weights(real_blender):
    """Issue: in Weight Paint mode on the field's terrain the grass (and its ground lying on the
    terrain) hid the weights. Now the field is hidden in the viewport while its terrain is in a
    paint mode (renders are not touched) and back when the artist leaves it: the screenshot in
    Weight Paint mode shows the weights (blue and red), the one in Object mode the grass again."""
    steps = [{"select": None}, {"python": TERRAIN}, {"select": "Terrain"},
             {"op": "windgrass.field_add", "args": {"use_selected_mesh": True}}, {"select": "Terrain"},
             {"view": {"look": [[0.0, -0.5, 9.0], [0.0, 0.0, 0.0]]}},
             {"wait": 1.0}, {"shot": "object_mode"}, {"python": HIDDEN},
             {"op": "object.mode_set", "args": {"mode": "WEIGHT_PAINT"}}, {"wait": 1.5},
             {"shot": "weight_paint"}, {"python": HIDDEN},
             {"op": "object.mode_set", "args": {"mode": "OBJECT"}}, {"wait": 1.5}, {"python": HIDDEN}]
    run = real_blender.run(steps)
    run.assert_clean()
    before, painting, after = [r for r in run.results("python") if isinstance(r, dict)]
    assert before["hidden"] == [False] and painting["hidden"] == [True] and after["hidden"] == [False]
    assert not painting["render_hidden"]  # (renders still show the grass)
    blue, red = _blue_red(run.shots / "weight_paint.png")
    assert blue > 0.02 and red > 0.02, (blue, red)  # the weights: 0 on the west half, 1 on the east
    blue0, red0 = _blue_red(run.shots / "object_mode.png")
    assert blue0 < blue / 4 and red0 < red / 4, (blue0, red0)  # in Object mode the grass covers them


KEYED_BALL = """
tracks = bridge("tracks")
tracks.AUTO_SAMPLE_S = -1.0  # (else the window samples by itself once the edit settles)
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(-1.0, 0.0, 0.3))
ball = bpy.context.active_object
ball.keyframe_insert("location", frame=1)
ball.location.x = 1.0
ball.keyframe_insert("location", frame=24)
coll = bpy.data.collections.new("Colliders")
bpy.context.scene.collection.children.link(coll)
for c in list(ball.users_collection):
    c.objects.unlink(ball)
coll.objects.link(ball)
bpy.context.scene.windgrass.fields[0].collider_collection = coll
result = True
"""

MOTION_STORED = """
tracks, properties = bridge("tracks"), bridge("properties")
scene = bpy.context.scene
item = scene.windgrass.fields[0]
wanted = tracks.fingerprint(scene, item, properties.params_from_settings(item, scene))
result = [tracks.stored_fingerprint(item) == wanted, scene.frame_current]
"""


def test_update_motion_samples_a_frame_at_a_time_in_the_window(real_blender):
    """Update Motion from the panel runs as a modal operator (a frame per tick, progress in the
    status bar, Esc to stop): it returns at once, the motion is stored a few seconds later (waited
    for as long as it takes) and the scene is back at its frame."""
    steps = [{"select": None}, {"op": "windgrass.field_add", "args": {"blocks_x": 2, "blocks_y": 2}},
             {"python": KEYED_BALL}, {"wait": 1.0}, {"python": MOTION_STORED},
             {"op": "windgrass.track_update", "invoke": True},
             {"settle": MOTION_STORED + "result = result == [True, 1]\n", "max": 600},
             {"python": MOTION_STORED},
             {"check": "fields"}]
    run = real_blender.run(steps, timeout=300)
    run.assert_clean()
    assert run.results("op")[-1] == ["RUNNING_MODAL"]
    before, after = run.results("python")[1:]
    assert before == [False, 1] and after == [True, 1]


def _field_band(path):
    """The 3D view's ground below the horizon seen from (0, -30, 6) (RGB 0..1): the cards' band
    and the far canopy beyond."""
    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    h, w = image.shape[:2]  # (rows 380-700 and columns 60-1000 of a 1280 x 800 screen)
    return image[h * 380 // 800:h * 700 // 800, w * 60 // 1280:w * 1000 // 1280]


# The largest 3D view's floor and axes, and where its centre (the origin, looked at) and bottom are
# on the screen (screenshots: x right, y down).
OVERLAYS = """
win = bpy.context.window_manager.windows[0]
area = max((a for a in win.screen.areas if a.type == 'VIEW_3D'), key=lambda a: a.width * a.height)
region = next(r for r in area.regions if r.type == 'WINDOW')
ov = area.spaces.active.overlay
result = {'flags': [ov.show_floor, ov.show_axis_x, ov.show_axis_y], 'shading': area.spaces.active.shading.type,
          'centre': [win.x + region.x + region.width // 2, win.height - (region.y + region.height // 2)],
          'bottom': win.height - region.y}
"""
# The file as saved: the floor and axes of its largest 3D view, read before any timer runs after
# the load.
REOPEN = """
win = bpy.context.window_manager.windows[0]
with bpy.context.temp_override(window=win, screen=win.screen):
    bpy.ops.wm.open_mainfile(filepath='{case}/floor.blend')
win = bpy.context.window_manager.windows[0]
area = max((a for a in win.screen.areas if a.type == 'VIEW_3D'), key=lambda a: a.width * a.height)
ov = area.spaces.active.overlay
result = {'flags': [ov.show_floor, ov.show_axis_x, ov.show_axis_y], 'shading': area.spaces.active.shading.type}
"""
ARTIST_TURNS_THE_FLOOR_ON = """
win = bpy.context.window_manager.windows[0]
area = max((a for a in win.screen.areas if a.type == 'VIEW_3D'), key=lambda a: a.width * a.height)
ov = area.spaces.active.overlay
ov.show_floor = ov.show_axis_x = ov.show_axis_y = True
area.tag_redraw()
result = True
"""


# The field's plants without leaves at their stems' foot: the axis lies on the ground (z = 0), which
# the leaves cover, hiding it with their depth as any mesh would; over thin blades it is the
# overlay's depth that decides, which this test is about.
LEAFLESS = """
for row in bpy.context.scene.windgrass.fields[0].blade.species:
    row.leaves = 'none'
result = sorted({row.leaves for row in bpy.context.scene.windgrass.fields[0].blade.species})
"""


def _axis_contrast(path, overlays):
    """How much brighter in green (0..255) the column of the Y axis is than the grass beside it,
    below the startup cube: the view looks from (0, -6, 2) at the origin, so the axis runs down
    the view's centre column towards the eye."""
    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)
    (x, y), bottom = overlays["centre"], overlays["bottom"]
    rows = image[y + 80:bottom - 30]
    line = rows[:, x - 1:x + 2, 1].mean(axis=1)
    beside = np.concatenate([rows[:, x - 14:x - 6, 1], rows[:, x + 7:x + 15, 1]], axis=1).mean(axis=1)
    return float((line - beside).mean())


def test_material_preview_reads_as_green_grass_without_the_floor_grid_over_it(real_blender):
    """Issue #28 item 6, Material Preview as Cycles shows the field.

    From 20-45 m the cards read as pale specks on dark ground: that is what Material Preview shows
    while Mesa compiles EEVEE's shaders (about a minute here; the screenshot "compiling" shows it,
    looked at, not asserted: its length varies; the test waits for the compilation to end); once
    compiled, the view of the card band and the far canopy is a green meadow (issue #34: its
    flowers and seed heads are the pale points it shows) with no black ground between them.

    The floor grid and axes drew over the grass everywhere (EEVEE gives the overlays a depth that
    thin blades do not hold; floor.py): while the view draws the field with EEVEE its floor and
    axes are off, so the axis running down the view is not seen over the grass; Solid shading gets
    them back; the saved file has them as the artist set them; an artist who turns them on again
    keeps them (a save too), and then the same measure sees the axis (it would catch it).

    The saves write a screenshot as the file's preview: Blender's own choice with a camera in the
    scene renders the camera's view for the preview: 300 s a save with Mesa's software GL here (the
    driver's step times; 1.7 s with a screenshot), and on a loaded CI machine the second save ran
    past the session's limit. The previews are not the subject."""
    far = {"view": {"look": [[0.0, -30.0, 6.0], [0.0, 5.0, 0.0]]}}
    preview = {"python": "bpy.context.preferences.filepaths.file_preview_type = 'SCREENSHOT'\n"
                         "result = bpy.context.preferences.filepaths.file_preview_type"}
    near = {"view": {"look": [[0.0, -6.0, 2.0], [0.0, 0.0, 0.0]]}}
    steps = [preview, *FIELD, {"python": LEAFLESS}, far, {"shading": "MATERIAL"}, {"wait": 5.0}, {"shot": "compiling"},
             {"settle": "shaders", "max": 900}, {"settle": "view", "max": 120}, {"shot": "compiled"},
             near, {"wait": 3.0}, {"python": OVERLAYS},
             {"shot": "near"},
             {"shading": "SOLID"}, {"python": OVERLAYS}, {"shading": "RENDERED"}, {"python": OVERLAYS},
             {"shading": "MATERIAL"}, {"save": "{case}/floor.blend"},
             {"python": OVERLAYS}, {"python": REOPEN}, {"wait": 20.0}, {"python": OVERLAYS},
             {"python": ARTIST_TURNS_THE_FLOOR_ON}, {"wait": 3.0}, {"python": OVERLAYS}, {"shot": "artist_on"},
             {"save": "{case}/floor.blend"}, {"wait": 1.0}, {"python": OVERLAYS}]
    # (a smaller screen than the other tests': EEVEE draws every pixel with Mesa's software GL, and
    # each step waits for the view; a safety net of a limit: the steps wait on progress)
    run = real_blender.run(steps, timeout=1500, width=960, height=600)
    run.assert_clean()
    rgb = _field_band(run.shots / "compiled.png")
    r, g, b = rgb.mean(axis=(0, 1))
    hue = 60.0 * ((b - r) / (g - min(r, b)) + 2.0)  # (g the largest: green's side of the hue circle)
    assert g > r and g > 1.2 * b and 70.0 < hue < 160.0, (r, g, b, hue)  # green (a meadow's: 84 deg on 5.2)
    # no pale specks on black ground, as a person sees the band once the view has gathered its
    # samples (the screen still): 4 x 4 pixel patches (the meadow's pale seed heads and flowers are
    # 6 % of the pixels here, 0.6 % of patches; 19 % of the pixels in a loaded CI's shot, taken
    # before the view stood still)
    h, w = (rgb.shape[0] // 4) * 4, (rgb.shape[1] // 4) * 4
    lum = rgb[:h, :w].reshape(h // 4, 4, w // 4, 4, 3).mean(axis=(1, 3, 4))
    assert (lum > 0.45).mean() < 0.1 and (lum < 0.02).mean() < 0.05

    python = run.results("python")
    previews, leafless, material, solid, rendered, saved, in_file, reopened, _, artist, saved_again = python
    assert previews == "SCREENSHOT" and leafless == ["none"]
    assert material["shading"] == "MATERIAL" and material["flags"] == [False, False, False]
    assert solid["shading"] == "SOLID" and solid["flags"] == [True, True, True]  # given back
    assert rendered["shading"] == "RENDERED" and rendered["flags"] == [False, False, False]  # (EEVEE: the startup's)
    assert saved["flags"] == [False, False, False]  # (off again after the save)
    assert in_file == {"flags": [True, True, True], "shading": "MATERIAL"}  # the file has them on
    assert reopened["flags"] == [False, False, False]  # the reopened file's Material Preview
    assert artist["flags"] == saved_again["flags"] == [True, True, True]  # the artist's choice stays, saved too
    hidden = _axis_contrast(run.shots / "near.png", material)
    shown = _axis_contrast(run.shots / "artist_on.png", artist)
    print(f"Y axis over the grass: {hidden:.1f} (floor off) / {shown:.1f} (the artist's floor on) of 255 in green")
    # (the axis is a green line, brighter than the grass: with the floor off no column stands out so;
    # one a little darker than the meadow's pale flowers beside it, -5 of 255, is no axis)
    assert shown > 20.0 and hidden < 5.0


def _drag(path: str, values, shots: str, every: int = 2) -> list[dict]:
    """A slider dragged through ``values`` (0.12 s a step, as a hand moves it), what the engine runs
    and a screenshot every ``every`` steps while the mouse is still down, then the release (the
    window's undo step)."""
    steps: list[dict] = []
    for i, value in enumerate(values):
        steps.append({"drag": path, "value": value, "wait": 0.12})
        if i % every == every - 1:
            steps += [{"probe": "engine"}, {"shot": f"{shots}{i}"}]
    return [*steps, {"set": path, "value": values[-1]}]


def test_dragging_the_wind_and_the_stiffness_the_grass_follows_while_the_mouse_is_down(real_blender):
    """Issue #58: an edit of the wind speed or the stiffness retunes the field (its new run on a
    thread, the grass of the value before shown meanwhile) and follows a drag while the mouse is
    still down (every FOLLOW_S, 0.3 s, one run behind: the engine runs a value the slider passed
    before the drag ends, the wind's rising with it, the stiffness falling); the viewport's
    grass moves from one screenshot to the next as the wind rises and the blades soften (the lower
    third of a low view, mean change over 0.5 %; looked at: the blades lean further each time)."""
    speeds, softer = [1.0, 2.5, 4.0, 5.5, 7.0, 8.5, 10.0, 11.5], [0.95, 0.85, 0.75, 0.65, 0.55, 0.45]
    steps = [*FIELD[:1], {"op": "windgrass.field_add"}, {"view": {"look": [[0.0, -7.0, 1.2], [0.0, 4.0, 0.1]]}},
             {"shading": "SOLID"}, {"wait": 1.5}, {"shot": "still"},
             *_drag("windgrass.fields[0].wind.speed", speeds, "wind"),
             {"set": "windgrass.fields[0].wind.speed", "value": 6.0}, {"wait": 1.0},
             *_drag("windgrass.fields[0].blade.stiffness", softer, "soft")]
    run = real_blender.run(steps)
    run.assert_clean()
    engine = [next(iter(r.values())) for r in run.results("probe")]
    wind, soft = engine[:4], engine[4:7]
    # (each value runs on a thread while the grass of the one before shows: the first probe may be the speed before)
    assert [e["wind_speed"] for e in wind[1:]] == sorted(e["wind_speed"] for e in wind[1:])
    assert wind[1]["wind_speed"] >= speeds[1] and wind[-1]["wind_speed"] >= speeds[5]  # followed while dragging
    assert soft[-1]["root_stiffness"] < soft[-2]["root_stiffness"]  # (the first may be the stiffness before)
    changes = {}
    for shots in (["still"] + [f"wind{i}" for i in (1, 3, 5, 7)], [f"soft{i}" for i in (1, 3, 5)]):
        images = [np.asarray(Image.open(run.shots / f"{name}.png").convert("L"), dtype=np.float64) / 255.0
                  for name in shots]
        h = images[0].shape[0]
        changes.update({b: float(np.abs(y - x)[int(0.6 * h):int(0.9 * h)].mean())
                        for a, b, x, y in zip(shots, shots[1:], images, images[1:])})
    assert min(changes.values()) > 0.005, changes


def test_no_step_of_a_drag_holds_the_window_for_a_second(real_blender):
    """Issue #58: dragging the wind speed, the stiffness and the density, the window answers the
    mouse throughout: each step's update (the value set: Windgrass's work in it, objects rebuilt
    for a density) holds the window at most 0.5 s, and no step of a drag (the value set, its
    update, 0.12 s) comes more than 1.5 s after the one before, or, on a machine loaded beside it,
    a second more than the slowest step of a drag of the render's resolution (which Windgrass
    draws nothing for: the window's own redraw of the field, software GL). The driver's steps run
    on the window's timer: a step late is the window held (the new run, the look and the new field
    are worked out on threads; before, a stiffness step held it 1.7-2.9 s, a density step 4-11 s)."""
    floor_path = "render.resolution_percentage"
    steps = [*FIELD[:1], {"op": "windgrass.field_add"}, {"shading": "SOLID"}, {"wait": 1.5},
             *[{"drag": floor_path, "value": v, "wait": 0.12} for v in (90, 80, 70, 60)],
             *[{"drag": "windgrass.fields[0].wind.speed", "value": v, "wait": 0.12} for v in (2.0, 4.0, 6.0, 8.0)],
             *[{"drag": "windgrass.fields[0].blade.stiffness", "value": v, "wait": 0.12} for v in (0.9, 0.7, 0.5)],
             *[{"drag": "windgrass.fields[0].field.density", "value": v, "wait": 0.12} for v in (400.0, 600.0, 800.0)]]
    run = real_blender.run(steps)
    run.assert_clean()
    gaps = {f"{b['step']['drag']} = {b['step']['value']}": round(b["at"] - a["at"], 2)
            for a, b in zip(run.steps, run.steps[1:]) if "drag" in a["step"] and "drag" in b["step"]}
    floor = max(g for name, g in gaps.items() if name.startswith(floor_path))
    edits = {name: g for name, g in gaps.items() if not name.startswith(floor_path)}
    took = {f"{s['step']['drag']} = {s['step']['value']}": s["took"] for s in run.steps
            if "drag" in s["step"] and not s["step"]["drag"].startswith(floor_path)}
    assert len(edits) == 10 and max(edits.values()) < max(1.5, floor + 1.0), (floor, edits, took)
    assert max(took.values()) < 0.5, took


def test_add_from_the_menu_builds_its_field_without_holding_the_window(real_blender):
    """Issue #58: Add Grass Field from the menu (the operator invoked, as the Add menu and F3 run
    it) makes the field's objects and returns: its engine (blocks, warm-up) is made on a thread,
    its look, first look and frame written by the timer. A 51 m field added that way (another seed:
    nothing of its look kept) holds the window under half as long as one added by a script (which
    builds at once), and draws about as many blades once built (looked at: the meadow from the
    startup view)."""
    size = {"blocks_x": 32, "blocks_y": 32}
    steps = [{"select": None}, {"op": "windgrass.field_add", "args": size}, {"wait": 1.0},
             {"op": "windgrass.field_add", "args": {**size, "seed": 7}, "invoke": True}, {"probe": "lod"},
             {"wait": 12.0}, {"shading": "SOLID"}, {"wait": 1.0}, {"probe": "lod"}, {"shot": "added"}]
    run = real_blender.run(steps)
    run.assert_clean()
    adds = [s for s in run.steps if s["step"].get("op") == "windgrass.field_add"]
    assert [s["result"] for s in adds] == [["FINISHED"], ["FINISHED"]]
    script, menu = (s["took"] for s in adds)
    assert menu < 0.5 * script, (menu, script)
    right_after, built = run.results("probe")
    assert list(right_after.values())[1] is None or not list(right_after.values())[1]["blades_drawn"]
    script_drawn, menu_drawn = (v["blades_drawn"] for v in built.values())
    assert script_drawn > 0 and abs(menu_drawn - script_drawn) <= 0.2 * script_drawn, built  # (another seed)
