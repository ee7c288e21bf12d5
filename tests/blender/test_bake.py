"""Bake: the field's animation into an Alembic cache beside the .blend, played by Mesh Sequence
Cache modifiers; the saved file renders the same grass in a Blender without Windgrass."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import bpy
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
W, H = 80, 45


@pytest.fixture
def bridge(with_bridge):
    import stage
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime

    return schema, properties, runtime, stage


def _scene(bridge):
    schema, properties, runtime, stage = bridge
    params = schema.defaults().replace({
        "field.blocks_x": 2, "field.blocks_y": 2, "field.cells_per_block": 8, "field.blades_per_cell": 3,
        "wind.type": "moderate_breeze", "wind.speed": 9.0, "camera.mode": "fixed",
        "camera.position": (0.0, -1.4, 0.45), "camera.target": (0.0, 0.2, 0.1), "lod.blade_near": 1.2,
        "lod.blade_far": 1.6, "lod.card_near": 2.0, "lod.card_far": 2.6,
        "render.samples": 4, "render.resolution_x": W, "render.resolution_y": H, "render.frame_end": 8})
    scene = bpy.context.scene
    stage.setup_stage(scene, params)
    stage.pose_camera(scene, params, 1)
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    return scene, item


def _pixels(path: Path) -> np.ndarray:
    image = bpy.data.images.load(str(path))
    try:
        return np.array(image.pixels[:], dtype=np.float32).reshape(H, W, 4)[..., :3]
    finally:
        bpy.data.images.remove(image)


RENDER_WITHOUT_WINDGRASS = textwrap.dedent("""
    import sys
    import bpy
    blend, out = sys.argv[-2], sys.argv[-1]
    bpy.ops.wm.open_mainfile(filepath=blend)
    assert "windgrass" not in sys.modules and not hasattr(bpy.types.Scene, "windgrass")
    scene = bpy.context.scene
    for frame in (3, 4, 5):
        scene.frame_set(frame)
        scene.render.filepath = f"{out}/frame_{frame}.png"
        bpy.ops.render.render(write_still=True)
    print("read me:", bpy.data.texts["Windgrass - read me"].as_string().splitlines()[0])
""")


def _without_windgrass(tmp_path, script: str, *args, out: str = "without"):
    """Run ``script`` in a fresh Python with Blender and no Windgrass (its own user folder) with
    ``args`` and an empty output folder last; returns (process, output folder)."""
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"), HOME=str(tmp_path))
    folder = tmp_path / out
    folder.mkdir()
    proc = subprocess.run([sys.executable, "-c", script, *map(str, args), str(folder)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return proc, folder


def test_a_baked_file_renders_the_live_grass_without_windgrass(bridge, tmp_path):
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    read_me = bpy.data.texts["Windgrass - read me"].as_string()
    assert "Live fields" in read_me and f"{scene.name} / {item.name}" in read_me  # says what it needs
    blend = tmp_path / "meadow.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    live = tmp_path / "live.png"
    scene.frame_set(4)
    scene.render.filepath = str(live)
    bpy.ops.render.render(write_still=True)

    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=6) == {"FINISHED"}
    files = sorted((tmp_path / "meadow_windgrass").rglob("*.abc"))
    assert len(files) == 1 and files[0].stat().st_size > 10_000
    assert all(b".velocities" in f.read_bytes() for f in files)  # motion blur from the cache too
    status = runtime.bake_status(scene, item)
    assert "Baked frames 1-6" in status and "stale" not in status
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))

    proc, out = _without_windgrass(tmp_path, RENDER_WITHOUT_WINDGRASS, blend)
    assert "read me: This file has grass fields of the Windgrass extension" in proc.stdout
    baked = {f: _pixels(out / f"frame_{f}.png") for f in (3, 4, 5)}
    assert np.abs(baked[4] - _pixels(live)).mean() < 2.0 / 255.0
    assert np.abs(baked[3] - baked[5]).mean() > 0.003  # the grass moves between frames


@pytest.mark.parametrize("fmt", ["alembic", "usd"])
def test_bake_reports_what_prevents_it(bridge, tmp_path, fmt):
    if fmt == "usd" and bpy.app.version < (5, 0, 0):
        pytest.skip("USD bakes need Blender 5.0+ (test_usd_bake_on_an_older_blender_says_why checks the sentence)")
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    with pytest.raises(RuntimeError, match="save the .blend first"):
        bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3, format=fmt)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "f.blend"))
    with pytest.raises(RuntimeError, match=r"frames 1-99 are not within the scene's frames 1-8"):
        bpy.ops.windgrass.field_bake(frame_start=1, frame_end=99, format=fmt)
    camera = scene.camera
    scene.camera = None
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3, format=fmt)
    scene.camera = camera
    (tmp_path / "f_windgrass").write_text("a file where the cache folder goes")
    with pytest.raises(RuntimeError, match="cannot write into"):
        bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3, format=fmt)
    assert runtime.bake_status(scene, item) is None  # still live, nothing half-made
    assert not list(tmp_path.rglob("*.usdc")) and not list(tmp_path.rglob("*.abc"))


def test_a_bake_whose_camera_sees_no_grass_says_so(bridge, tmp_path, capfd):
    """The camera turned to the sky: the bake is written (nothing refused it) and the artist is
    told it holds no grass, where a seen field's bake says nothing of the kind."""
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "f.blend"))
    capfd.readouterr()
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=2) == {"FINISHED"}
    assert "sees none of" not in capfd.readouterr().out
    assert bpy.ops.windgrass.field_bake_free() == {"FINISHED"}
    scene.camera.animation_data_clear()
    scene.camera.location, scene.camera.rotation_euler = (0.0, 0.0, 5.0), (math.pi, 0.0, 0.0)  # up, at the sky
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=2) == {"FINISHED"}
    assert f"The scene camera sees none of '{item.name}' in frames 1-2" in capfd.readouterr().out


def test_an_edit_makes_the_bake_stale_and_free_bake_goes_live(bridge, tmp_path):
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "g.blend"))
    assert bpy.ops.windgrass.field_bake(frame_start=2, frame_end=3) == {"FINISHED"}
    item.wind.speed = 3.0
    assert "stale: parameters changed" in runtime.bake_status(scene, item)
    scene.camera.data.lens += 5.0  # (its path is keyed: moving it without a key changes nothing)
    assert "camera changed" in runtime.bake_status(scene, item)
    assert bpy.ops.windgrass.field_bake_free() == {"FINISHED"}
    assert runtime.bake_status(scene, item) is None
    assert not bpy.data.cache_files
    scene.frame_set(5)
    assert runtime.get_runtime(scene, item).frame == 5  # written live again
    assert list((tmp_path / "g_windgrass").rglob("*.abc"))  # kept while an undo could bring the bake back
    bpy.ops.wm.save_mainfile()
    assert not (tmp_path / "g_windgrass").exists()  # the saved file refers to none: deleted


def test_a_stopped_bake_leaves_nothing_and_the_grass_live(bridge, tmp_path):
    """What Esc does in the panel: the bake runs a group of objects per step; stopping after the
    first deletes what was written and the field stays live."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "h.blend"))
    baker = runtime.start_bake(scene, item, 1, 4, groups=2)
    assert len(baker.groups) == 2 and baker.progress == 0.0
    assert baker.step() is False and baker.progress == 0.5
    assert len(list((tmp_path / "h_windgrass").rglob("*.abc"))) == 1
    baker.cancel()
    assert not list((tmp_path / "h_windgrass").rglob("*.abc"))
    assert runtime.bake_status(scene, item) is None
    assert not any(m.name == "Windgrass bake" for o in item.collection.objects for m in o.modifiers)
    scene.frame_set(6)
    assert runtime.get_runtime(scene, item).frame == 6


def test_the_bake_is_stale_when_the_camera_keys_change_not_when_it_moves_along_them(bridge, tmp_path):
    """Issue: on Blender 5.0 the camera's keys were not seen (layered actions), and with an
    animated camera every frame but one said "stale: camera changed" (its pose was hashed)."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    cam = scene.camera
    cam.location = (0.0, -1.4, 0.45)
    cam.keyframe_insert("location", frame=1)
    cam.location = (0.3, -1.2, 0.45)
    cam.keyframe_insert("location", frame=8)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "k.blend"))
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3) == {"FINISHED"}
    for frame in (1, 2, 5, 8):
        scene.frame_set(frame)  # the camera moves along its keys
        assert "stale" not in runtime.bake_status(scene, item), frame
    cam.location = (0.0, -1.0, 0.6)
    cam.keyframe_insert("location", frame=5)  # a new key: another path
    assert "camera changed" in runtime.bake_status(scene, item)


def test_a_bake_that_would_fill_the_disk_is_refused_and_writes_nothing(bridge, tmp_path):
    """Issue: a full disk during a bake aborted Blender (SIGABRT from the Alembic writer) and left
    a partial .abc. The bake checks the space it needs first. The disk: a 3 MB tmpfs."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs (a nearly full disk) needs root")
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    small = tmp_path / "small"
    small.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(small)], check=True)
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(small / "full.blend"))
        with pytest.raises(RuntimeError, match=r"needs about [\d,]+ MB but the disk .* has [\d,]+ MB free"):
            bpy.ops.windgrass.field_bake(frame_start=1, frame_end=8)
        assert sorted(p.name for p in small.iterdir()) == ["full.blend"]  # no cache folder, no partial file
        assert runtime.bake_status(scene, item) is None
        assert not any(m.name == "Windgrass bake" for o in item.collection.objects for m in o.modifiers)
    finally:
        bpy.ops.wm.read_factory_settings(use_empty=True)  # let go of the file before unmounting
        subprocess.run(["umount", str(small)], check=True)


def test_a_disk_filled_by_another_writer_between_parts_of_a_bake_stops_it_with_a_sentence(bridge, tmp_path):
    """Issue #37 item 10: a disk filled by another program mid-bake aborted Blender in the Alembic
    writer. The bake looks again before each part it writes: once the disk is full it stops with a
    sentence, keeps nothing and leaves the field live (the part in progress when another program
    fills the disk is Blender's own writer's). The disk: a tmpfs with room for the bake at first."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs (a nearly full disk) needs root")
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    need = runtime.bake.estimate_bytes(item, 1, 8)
    small = tmp_path / "small"
    small.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={(need >> 10) + 8192}k", "tmpfs", str(small)], check=True)
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(small / "busy.blend"))
        baker = runtime.start_bake(scene, item, 1, 8, groups=2)
        assert baker.step() is False  # the first part is written
        free = runtime.bake.free_bytes(small)
        with open(small / "other program's file", "wb") as other:  # another writer takes the disk
            other.write(b"\0" * (free - 50_000))
        with pytest.raises(runtime.bake.BakeError, match=r"filled while baking: the next part needs about "
                                                           r"[\d.,]+ MB and 0\.\d MB are free"):
            baker.step()
        assert sorted(p.name for p in small.rglob("*") if p.is_file()) == ["busy.blend", "other program's file"]
        assert runtime.bake_status(scene, item) is None
        assert not any(m.name == "Windgrass bake" for o in item.collection.objects for m in o.modifiers)
        scene.frame_set(5)
        assert runtime.get_runtime(scene, item).frame == 5  # live
    finally:
        bpy.ops.wm.read_factory_settings(use_empty=True)  # let go of the file before unmounting
        subprocess.run(["umount", str(small)], check=True)


def _abc(tmp_path, stem):
    return sorted(p.name for p in (tmp_path / f"{stem}_windgrass").rglob("*.abc"))


def test_undo_of_free_bake_finds_its_files_and_undo_of_a_bake_leaves_none(bridge, tmp_path):
    """Issue: undo of Free Bake brought back a bake whose files were gone (the grass froze, the
    status said baked); undo of a bake left its .abc orphaned on disk."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "u.blend"))
    bpy.ops.ed.undo_push(message="saved")
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="bake")
    files = _abc(tmp_path, "u")
    assert bpy.ops.windgrass.field_bake_free() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="free")
    bpy.ops.ed.undo()  # Free Bake undone: baked again, and its files are there
    scene, item = bpy.context.scene, bpy.context.scene.windgrass.fields[0]
    status = runtime.bake_status(scene, item)
    assert status.startswith("Baked frames 1-3") and "missing" not in status
    assert _abc(tmp_path, "u") == files and runtime.plays_cache(item)
    bpy.ops.ed.undo()  # the bake undone: live, and once the work is saved its files are gone
    scene, item = bpy.context.scene, bpy.context.scene.windgrass.fields[0]
    assert runtime.bake_status(scene, item) is None
    bpy.ops.wm.save_mainfile()
    assert not (tmp_path / "u_windgrass").exists()


def test_a_baked_file_whose_cache_was_deleted_says_so_and_plays_live(bridge, tmp_path):
    """Issue: opening a baked file whose cache folder was deleted said nothing; the grass froze."""
    import shutil

    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    path = tmp_path / "d.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3) == {"FINISHED"}
    bpy.ops.wm.save_mainfile()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    shutil.rmtree(tmp_path / "d_windgrass")
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    status = runtime.bake_status(scene, item)
    assert "cache files are missing" in status and "plays live" in status
    scene.frame_set(2)
    before = _frame_pixels_free_positions(item)
    scene.frame_set(3)
    assert runtime.get_runtime(scene, item).frame == 3  # written live
    assert not np.array_equal(before, _frame_pixels_free_positions(item))  # and it moves


def _frame_pixels_free_positions(item):
    obj = next(o for o in item.collection.objects if o.get("wg_role") == "blades")
    dg = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(dg).to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
    finally:
        obj.evaluated_get(dg).to_mesh_clear()
    assert co.size and np.abs(co).max() > 0  # the renderer sees grass
    return co


def test_an_undo_during_a_panel_bake_keeps_nothing(bridge, tmp_path):
    """Issue: Ctrl+Z during a panel bake raised ReferenceError in the modal step, never ended the
    progress bar and left 5.9 MB of cache. The panel's bake now takes the keys itself (no undo
    reaches Blender meanwhile); should the scene change under it all the same, the step's
    ReferenceError ends it and what it wrote is deleted (Baker.abandon touches no Blender data)."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "z.blend"))
    bpy.ops.ed.undo_push(message="saved")
    baker = runtime.start_bake(scene, item, 1, 4, groups=2)
    assert baker.step() is False and _abc(tmp_path, "z")
    bpy.ops.ed.undo_push(message="baking")
    bpy.ops.ed.undo()  # what the bake holds is gone
    with pytest.raises(ReferenceError):
        baker.step()
    baker.abandon()
    assert not (tmp_path / "z_windgrass").exists()


# --- USD (issue #30): the same bake as time-sampled USD meshes, read with Pixar's own library -----

def _usd():
    usd = pytest.importorskip("pxr.Usd", reason="usd-core (pip) reads the USD files")
    from pxr import UsdGeom, UsdShade, UsdValidation

    return usd, UsdGeom, UsdShade, UsdValidation


def _usd_bake(bridge, tmp_path, first=1, last=6):
    if bpy.app.version < (5, 0, 0):
        pytest.skip("USD bakes need Blender 5.0+ (test_usd_bake_on_an_older_blender_says_why checks the sentence)")
    scene, item = _scene(bridge)
    blend = tmp_path / "meadow.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    live = tmp_path / "live.png"
    scene.frame_set(4)
    for blur, path in ((True, tmp_path / "live_blur.png"), (False, live)):
        scene.render.use_motion_blur = blur
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
    assert bpy.ops.windgrass.field_bake(frame_start=first, frame_end=last, format="usd") == {"FINISHED"}
    files = sorted((tmp_path / "meadow_windgrass").rglob("*.usdc"))
    assert len(files) == 1 and files[0].stat().st_size > 10_000
    return scene, item, blend, live, files[0]


def test_usd_bake_has_a_sample_at_every_frame_with_velocities_and_extents(bridge, tmp_path):
    """Every frame a sample of points, velocities and extent; as many velocities as points; the
    extent bounds the points; velocities advanced by one frame predict the next frame's points
    (better than holding the points still: blades turn about their roots, so a straight step
    misses by the curvature of their arcs); Pixar's validators find no error."""
    Usd, UsdGeom, UsdShade, UsdValidation = _usd()
    scene, item, blend, live, path = _usd_bake(bridge, tmp_path)
    stage = Usd.Stage.Open(str(path))
    fps = scene.render.fps / scene.render.fps_base
    assert stage.GetTimeCodesPerSecond() == pytest.approx(fps)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert sorted(m.GetPrim().GetName() for m in meshes) == sorted(
        bpy.path.clean_name(o.data.name) for o in item.collection.objects if o.get("wg_role") in ("blades", "cards"))
    frames = list(range(1, 7))
    misses, steps = [], []
    for mesh in meshes:
        assert list(mesh.GetPointsAttr().GetTimeSamples()) == frames
        assert list(mesh.GetVelocitiesAttr().GetTimeSamples()) == frames
        assert list(mesh.GetExtentAttr().GetTimeSamples()) == frames
        names = {p.GetPrimvarName() for p in UsdGeom.PrimvarsAPI(mesh).GetPrimvars()}
        assert "UVMap" in names and names & {"wg_tint_rg", "wg_fade"}  # what the materials read
        shown = np.array(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor").ComputeFlattened(1), np.float64)
        shown = shown[shown.sum(axis=1) > 0]  # (a slot's unused blades have no colour)
        red, green, blue = np.median(shown, axis=0)  # the colour any renderer shows: grass green
        assert green > 1.5 * red and green > 1.5 * blue, (mesh.GetPrim().GetName(), shown.shape, red, green, blue)
        material = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()[0]
        shaders = [UsdShade.Shader(p) for p in Usd.PrimRange(material.GetPrim()) if p.IsA(UsdShade.Shader)]
        assert any(s.GetIdAttr().Get() == "UsdPreviewSurface" for s in shaders)
        for reader in (s for s in shaders if s.GetIdAttr().Get().startswith("UsdPrimvarReader_")):
            primvar = UsdGeom.PrimvarsAPI(mesh).GetPrimvar(reader.GetInput("varname").Get())
            width = {"float2": 2, "float3": 3}[reader.GetIdAttr().Get().split("_")[-1]]
            assert primvar and primvar.GetTypeName().scalarType.type.pythonClass.dimension == width, reader.GetPath()
        for frame in frames:
            points = np.array(mesh.GetPointsAttr().Get(frame), dtype=np.float64)
            velocities = np.array(mesh.GetVelocitiesAttr().Get(frame), dtype=np.float64)
            assert velocities.shape == points.shape
            lo, hi = np.array(mesh.GetExtentAttr().Get(frame), dtype=np.float64)
            assert np.all(points >= lo - 1e-6) and np.all(points <= hi + 1e-6)
            if frame < frames[-1]:
                after = np.array(mesh.GetPointsAttr().Get(frame + 1), dtype=np.float64)
                moving = np.linalg.norm(after - points, axis=1) > 1e-5
                misses.append(np.linalg.norm(after - (points + velocities / fps), axis=1)[moving])
                steps.append(np.linalg.norm(after - points, axis=1)[moving])
    miss, step = np.concatenate(misses), np.concatenate(steps)
    ratio = float(np.median(miss) / np.median(step))
    print(f"USD velocities: median miss {np.median(miss) * 1e3:.2f} mm of a median step "
          f"{np.median(step) * 1e3:.2f} mm per frame ({ratio:.2f})")
    assert ratio < 0.5
    context = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e for e in context.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert not errors, [e.GetErrorAsString() for e in errors]


def _drawn_uvs(scene, objects, names) -> dict:
    """{(object, UV map): (corners, 2)} of what Blender draws now (the evaluated meshes)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    for obj in objects:
        mesh = obj.evaluated_get(depsgraph).data
        for name in names:
            layer = mesh.uv_layers.get(name)
            if layer is not None:
                uv = np.empty(len(layer.data) * 2, np.float32)
                layer.data.foreach_get("uv", uv)
                out[obj.name, name] = uv.reshape(-1, 2)
    return out


def test_a_usd_bake_samples_the_tints_and_fades_of_each_frame(bridge, tmp_path):
    """Issue #36 item 6, every slot sampled every frame: as the camera moves back a slot's blades
    show other blocks (other tints) and the cards fade; at every frame the USD's tints and fades,
    as any USD reader computes them (values, indices, interpolation), are those Blender drew at it
    (the bake's finishing pass, ``usd_finish``, rewrites the file: it must keep them)."""
    if bpy.app.version < (5, 0, 0):
        pytest.skip("USD bakes need Blender 5.0+")
    Usd, UsdGeom, _, _ = _usd()
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    cam = scene.camera
    cam.animation_data_clear()
    for frame, y in ((1, -1.4), (6, -3.2)):  # (back over the field: blades become cards, cards fade)
        cam.location = (0.0, y, 0.45 + 0.1 * (frame - 1))
        cam.keyframe_insert("location", frame=frame)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "moving.blend"))
    slots = [o for o in item.collection.objects if o.get("wg_role") in ("blades", "cards")]
    names = ("wg_tint_rg", "wg_tint_bs", "wg_fade")
    drawn = {}
    for frame in range(1, 7):
        scene.frame_set(frame)
        drawn[frame] = _drawn_uvs(scene, slots, names)
    changed = {key[1] for key in drawn[1] if not np.array_equal(drawn[1][key], drawn[6][key])}
    assert {"wg_tint_rg", "wg_fade"} <= changed  # (what the bake must follow)
    paths = {o.name: runtime.bake.object_path("usd", o) for o in slots}
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=6, format="usd") == {"FINISHED"}
    stage = Usd.Stage.Open(str(next((tmp_path / "moving_windgrass").rglob("*.usdc"))))
    for frame, uvs in drawn.items():
        for (name, uv_name), expected in uvs.items():
            primvar = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(paths[name])).GetPrimvar(uv_name)
            got = np.array(primvar.ComputeFlattened(float(frame)), np.float32)
            assert got.shape == expected.shape and np.allclose(got, expected, atol=1e-6), (frame, name, uv_name)


def test_a_usd_baked_file_renders_the_live_grass_without_windgrass(bridge, tmp_path):
    """The saved file plays the USD through Blender's USD reader (Mesh Sequence Cache modifiers,
    as Blender's own USD import makes them): rendered by a Blender without Windgrass, the frame is
    the live add-on's."""
    scene, item, blend, live, path = _usd_bake(bridge, tmp_path)
    modifiers = [m for o in item.collection.objects for m in o.modifiers if m.type == "MESH_SEQUENCE_CACHE"]
    assert modifiers and all(m.cache_file.filepath.endswith(".usdc") for m in modifiers)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    proc, out = _without_windgrass(tmp_path, RENDER_WITHOUT_WINDGRASS, blend)
    assert "Could not create cache reader" not in proc.stdout + proc.stderr
    baked = {f: _pixels(out / f"frame_{f}.png") for f in (3, 4, 5)}
    assert np.abs(baked[4] - _pixels(live)).mean() < 2.0 / 255.0
    assert np.abs(baked[3] - baked[5]).mean() > 0.003  # the grass moves between frames


IMPORT_USD_WITHOUT_WINDGRASS = textwrap.dedent("""
    import sys
    import bpy
    blend, usd, out = sys.argv[-3], sys.argv[-2], sys.argv[-1]
    bpy.ops.wm.open_mainfile(filepath=blend)
    assert "windgrass" not in sys.modules and not hasattr(bpy.types.Scene, "windgrass")
    grass = [o for o in bpy.data.objects if o.get("wg_role") in ("blades", "cards")]
    bpy.data.batch_remove(grass)  # the scene without its grass, which comes back from the USD alone
    bpy.ops.wm.usd_import(filepath=usd, mtl_name_collision_mode="REFERENCE_EXISTING", set_frame_range=False,
                          import_cameras=False, import_lights=False, create_world_material=False)
    imported = [o for o in bpy.data.objects if o.type == "MESH" and o.get("wg_role") in ("blades", "cards")]
    # USD names are identifiers ("Grass blades" is written "Grass_blades"): the shot's own materials
    # are bound again by their Blender names, as a look file's binding would
    for obj in imported:
        for i, mat in enumerate(obj.data.materials):
            obj.data.materials[i] = bpy.data.materials.get(mat.name.replace("_", " ")) or mat
    print("imported:", sorted((o.name, [m.name for m in o.data.materials], [u.name for u in o.data.uv_layers],
                               [m.type for m in o.modifiers]) for o in imported))
    scene = bpy.context.scene
    scene.frame_set(4)
    for blur, name in ((False, "frame_4"), (True, "frame_4_blur")):
        scene.render.use_motion_blur = blur
        scene.render.filepath = f"{out}/{name}.png"
        bpy.ops.render.render(write_still=True)
""")


def test_the_usd_imported_into_a_blender_without_windgrass_renders_the_live_grass(bridge, tmp_path):
    """Round trip: the scene without its grass, the USD imported by Blender's own importer (the
    materials found by name, as a shot's look file provides them): frame 4 renders as live."""
    scene, item, blend, live, path = _usd_bake(bridge, tmp_path)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    proc, out = _without_windgrass(tmp_path, IMPORT_USD_WITHOUT_WINDGRASS, blend, path, out="imported")
    frame = _pixels(out / "frame_4.png")
    assert np.abs(frame - _pixels(live)).mean() < 2.0 / 255.0
    # motion blur from the USD's velocities: as the live add-on's, and visibly not the sharp frame
    blurred, live_blurred = _pixels(out / "frame_4_blur.png"), _pixels(tmp_path / "live_blur.png")
    blur = np.abs(live_blurred - _pixels(live)).mean()
    assert blur > 0.5 / 255.0
    assert np.abs(blurred - live_blurred).mean() < min(2.0 / 255.0, 0.25 * blur)


def test_usd_bake_on_an_older_blender_says_why_and_writes_nothing(bridge, tmp_path):
    """Blender 4.2's USD writer keeps a moving mesh's extent at its first frame (renderers cull the
    grass by it): there a USD bake is a sentence naming what to do, and nothing is written."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "old.blend"))
    from windgrass.grass_addon.errors import WindgrassError

    with pytest.raises(WindgrassError, match="bake: unknown format 'obj' \\(valid: alembic, usd\\)"):
        runtime.bake_field(scene, item, 1, 3, fmt="obj")
    if bpy.app.version >= (5, 0, 0):
        assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=2, format="usd") == {"FINISHED"}
        return
    with pytest.raises(RuntimeError, match="USD needs Blender 5.0 or later.*bake to Alembic here"):
        bpy.ops.windgrass.field_bake(frame_start=1, frame_end=3, format="usd")
    assert runtime.bake_status(scene, item) is None and not (tmp_path / "old_windgrass").exists()


def test_a_bake_of_one_loop_plays_round_and_round(bridge, drawn, tmp_path):
    """Issue #61: a field that loops every 1 s (24 frames), baked over frames 1-24, plays frame
    24 + k as frame k from its cache, in the meshes Blender draws, with no driver (animation data:
    a farm node runs no script for it); the live field drew the same at frame 3 and at frame 27."""
    _, _, runtime, _ = bridge
    scene, item = _scene(bridge)
    item.simulation.preroll, item.simulation.epoch, item.simulation.loop = 0.5, 0.5, 1.0
    scene.frame_end = 48
    scene.frame_set(3)
    live = drawn(item, "blades")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "loop.blend"))
    assert bpy.ops.windgrass.field_bake(frame_start=1, frame_end=24) == {"FINISHED"}
    cache = next(c for c in bpy.data.cache_files if c.get("wg_uid"))
    assert cache.override_frame and not any(d.driver for d in (cache.animation_data.drivers or ()))
    for frame in (3, 27, 51):
        scene.frame_set(frame)
        np.testing.assert_allclose(drawn(item, "blades"), live, atol=1e-5)
    scene.frame_set(4)
    assert not np.allclose(drawn(item, "blades"), live, atol=1e-5), "the bake stood still"
