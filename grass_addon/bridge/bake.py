"""Bake: a field's animation over a frame range into an Alembic or a USD cache beside the .blend.

The field's slot objects then play the cache through Mesh Sequence Cache modifiers, stock Blender,
so the saved .blend plays and renders frame for frame like the live field in a Blender without
Windgrass (render farms, other departments). What is baked is what the scene camera saw over the
range: the LOD followed the camera while the frames were written. Every per-frame datum of a slot
is in its positions and UV maps (materials.py), which Alembic keeps per frame. USD (``FORMATS``)
holds the same: time-sampled points, velocities and extents, the UV maps as primvars, the
materials as preview surfaces, for renderers and pipelines outside Blender; the field plays it
through the same modifier.

The record ``item["wg_bake"]`` says what the bake was made from (parameters digest, camera), so a
later edit or camera move is reported as a stale bake. Free Bake returns to the live simulation.

The files on disk follow what a file refers to, through undo: every bake writes files of its own
names (``group_00_<bake>.abc`` or ``.usdc``), Free Bake and undo only drop references, and the files no field
refers to are deleted when the .blend is saved (those the saved file does not use), when Blender
leaves the file (open, new, quit: those the file on disk does not use). So undoing Free Bake finds
its files, undoing a bake leaves nothing behind once the work is saved or left, and a field whose
files are missing (a cache folder deleted by hand) says so and plays live (``files_present``).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import uuid
from pathlib import Path

import bpy
import numpy as np

from .. import loop, roles
from ..errors import WindgrassError
from ..folders import ensure_writable
from . import animation, heads, owned, usd_finish
from . import scene as field_scene
from .registry import REGISTRY, key_of

RECORD = "wg_bake"
MODIFIER = "Windgrass bake"
ROLES = roles.NAMES
# The formats a bake writes: (file extension, the build option Blender needs, the name shown).
FORMATS = {"alembic": (".abc", "alembic", "Alembic"), "usd": (".usdc", "usd", "USD")}
USD_SINCE = (5, 0, 0)  # the oldest Blender whose USD writer samples a moving mesh's extent each frame (tested)


class BakeError(WindgrassError):
    """A bake cannot be made (unsaved file, no camera, frames outside the scene, folder not writable)."""


def is_baked(item) -> bool:
    return item.get(RECORD) is not None


def cache_folder(item) -> Path:
    """``<blend folder>/<blend name>_windgrass/<field uid>/``; BakeError for an unsaved file."""
    if not bpy.data.filepath:
        raise BakeError("bake: save the .blend first (the cache is written beside it)")
    blend = Path(bpy.data.filepath)
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(item.uid))
    return blend.parent / f"{blend.stem}_windgrass" / safe


TRANSFORM = ("location", "rotation_euler", "rotation_quaternion", "scale")


def _curves(id_block) -> dict[tuple[str, int], bytes]:
    """{(data path, index): its keys and handles} of an ID's animation (Blender 5.0's layered
    actions too, through ``animation.action_fcurves``)."""
    out = {}
    for fcurve in animation.action_fcurves(getattr(id_block, "animation_data", None)):
        n = len(fcurve.keyframe_points)
        keys = np.empty(n * 6, np.float32)
        if n:
            fcurve.keyframe_points.foreach_get("co", keys[:2 * n])
            fcurve.keyframe_points.foreach_get("handle_left", keys[2 * n:4 * n])
            fcurve.keyframe_points.foreach_get("handle_right", keys[4 * n:])
        extra = f"{fcurve.extrapolation}|{fcurve.mute}|" + ",".join(k.interpolation for k in fcurve.keyframe_points)
        out[(fcurve.data_path, fcurve.array_index)] = keys.tobytes() + extra.encode()
    return out


def camera_fingerprint(scene) -> str:
    """What the scene camera's path depends on: which camera, its lens, its keys, and the
    transform values no key drives. Not its pose at the current frame: with an animated camera
    that changes every frame, and the bake is no staler for it."""
    cam = scene.camera
    if cam is None:
        return ""
    h = hashlib.sha1(cam.name.encode())
    curves = _curves(cam)
    for path in TRANSFORM:
        for index, value in enumerate(getattr(cam, path)):
            if (path, index) not in curves:
                h.update(f"{path}[{index}]={value:.6g}".encode())
    h.update(repr(cam.rotation_mode).encode())
    for key in sorted(curves):
        h.update(repr(key).encode() + curves[key])
    if cam.type == "CAMERA":
        data = cam.data
        h.update(repr((round(data.lens, 6), round(data.sensor_width, 6), data.sensor_fit, data.type,
                       round(data.ortho_scale, 6), round(data.shift_x, 6), round(data.shift_y, 6))).encode())
        for key, keys in sorted(_curves(data).items()):
            h.update(repr(key).encode() + keys)
    return h.hexdigest()


def missing_build_feature(fmt: str = "alembic") -> str | None:
    """Why this Blender cannot bake to ``fmt`` (it was built without Alembic, as Debian's is), or
    None; an unknown format is named with the valid ones."""
    if fmt not in FORMATS:
        return f"bake: unknown format {fmt!r} (valid: {', '.join(FORMATS)})"
    name = FORMATS[fmt][2]
    since = f"{USD_SINCE[0]}.{USD_SINCE[1]}"
    here = f"{bpy.app.version[0]}.{bpy.app.version[1]}"
    built = {f: bool(getattr(bpy.app.build_options, FORMATS[f][1], True)) for f in FORMATS}  # (what it can write)
    usd_ok = built["usd"] and bpy.app.version >= USD_SINCE
    if not built["alembic"] and not usd_ok:  # (each format would point to the other: neither works here)
        usd_why = ("without USD" if not built["usd"] else
                   f"with a USD writer that keeps a moving mesh's extent at its first frame (fixed in {since})")
        return (f"bake: this Blender {here} can bake to neither Alembic nor USD: it was built without Alembic and "
                f"{usd_why}; bake in a Blender from blender.org, whose builds have both")
    if fmt == "usd" and built["usd"] and not usd_ok:
        return (f"bake: USD needs Blender {since} or later (the USD writer of {here} keeps a moving mesh's extent, "
                f"the bounds renderers cull by, at its first frame); bake to Alembic here, or to USD in Blender "
                f"{since}+")
    if not built[fmt]:
        other = "USD" if fmt == "alembic" else "Alembic"
        return (f"bake: this Blender was built without {name}, the format asked for; bake to {other} here, or in a "
                f"Blender from blender.org (its builds have {name})")
    return None


def check(scene, item, first: int, last: int, fmt: str = "alembic") -> Path:
    """The cache's folder, once everything a bake needs is there; BakeError naming what is not.
    Nothing is written before every check has passed."""
    missing = missing_build_feature(fmt)
    if missing:
        raise BakeError(missing)
    if item.collection is None or not any(owned.slot_objects(item, role) for role in ROLES):
        raise BakeError(f"bake: field '{item.name}' has no objects; add or rebuild it first")
    if scene.camera is None:
        raise BakeError("bake: the scene has no camera (the bake holds what the camera sees; set Scene > Camera)")
    if not (scene.frame_start <= first <= last <= scene.frame_end):
        raise BakeError(f"bake: frames {first}-{last} are not within the scene's frames "
                        f"{scene.frame_start}-{scene.frame_end} (valid: start <= first <= last <= end)")
    folder = cache_folder(item)
    need, free = estimate_bytes(item, first, last), free_bytes(folder)
    if free is not None and need > free:
        raise BakeError(f"bake: the cache of frames {first}-{last} needs about {need / 1e6:,.0f} MB but the disk "
                        f"of {folder.parent} has {free / 1e6:,.0f} MB free; free some space or bake fewer frames")
    try:
        ensure_writable(folder)
    except OSError as exc:
        raise BakeError(f"bake: cannot write into {folder}: {exc.strerror or exc}") from None
    return folder


# What Alembic may write per frame and slot vertex (position and velocity, 12 bytes each) and per
# face corner and UV map (8 bytes): an upper estimate (the files measured a third of it; a full
# disk aborts Blender's Alembic writer, so a bake checks first).
BYTES_PER_VERTEX, BYTES_PER_CORNER_MAP, OVERHEAD = 24, 8, 1.0


def estimate_bytes(item, first: int, last: int, objects=None) -> int:
    """About how many bytes a bake of frames ``first``-``last`` writes (an upper estimate); of
    ``objects`` only (a group of the bake), else of every slot."""
    per_frame = 0
    for obj in _slots(item) if objects is None else objects:
        mesh = obj.data
        per_frame += len(mesh.vertices) * BYTES_PER_VERTEX
        per_frame += len(mesh.loops) * BYTES_PER_CORNER_MAP * len(mesh.uv_layers)
    return int(OVERHEAD * per_frame * (int(last) - int(first) + 1)) + (1 << 20)


def free_bytes(folder: Path) -> int | None:
    """Free bytes on the disk that holds ``folder`` (or its nearest existing parent)."""
    path = Path(folder)
    while not path.exists() and path.parent != path:
        path = path.parent
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


def _slots(item) -> list:
    return [obj for role in ROLES for obj in owned.slot_objects(item, role).values()]


def _abc_name(name: str) -> str:
    """A name as Alembic writes it (spaces, dots and colons become underscores)."""
    return "".join("_" if c in " .:" else c for c in name)


def _usd_name(name: str) -> str:
    """A name as Blender's USD exporter writes it (a valid identifier: letters, digits and
    underscores, not starting with a digit)."""
    out = "".join(c if c.isascii() and (c.isalnum() or c == "_") else "_" for c in name)
    return "_" + out if not out or out[0].isdigit() else out


def object_path(fmt: str, obj) -> str:
    """Where a slot object's mesh is in a bake's file (the Mesh Sequence Cache's object path)."""
    if fmt == "usd":  # under its parents' prims (a slot is the ground's child)
        chain = [obj.data.name]
        while obj is not None:
            chain.append(obj.name)
            obj = obj.parent
        return "/root/" + "/".join(_usd_name(name) for name in reversed(chain))
    return f"/{_abc_name(obj.name)}/{_abc_name(obj.data.name)}"


class Baker:
    """One bake, step by step: each ``step`` exports one group of slot objects (all the frames)
    into its own Alembic file, so a long bake in the panel shows its progress and can stop between
    groups (``cancel``: nothing is left, the field stays live). ``finish`` plays the field from
    the files.

    A mesh rewritten from Python exports as static unless it carries a modifier: a no-op one makes
    the exporter write every frame. With motion blur forced on meanwhile, each frame carries its
    velocities (Alembic ".velocities"), which the cache gives Cycles back in any Blender."""

    def __init__(self, scene, item, first: int, last: int, digest: str, groups: int = 1, fmt: str = "alembic"):
        """``groups``: how many exports (and files) to split the objects into: more steps to show
        progress and stop between, but each export simulates every frame again and the files
        share less data (scripts: 1; the panel: a few). ``fmt``: a key of ``FORMATS``."""
        self.folder = check(scene, item, first, last, fmt)
        free_bake(scene, item)
        self.scene, self.item, self.first, self.last, self.digest = scene, item, int(first), int(last), digest
        self.fmt = fmt
        objects = _slots(item)
        size = max(1, -(-len(objects) // max(1, int(groups))))
        self.groups = [objects[i:i + size] for i in range(0, len(objects), size)]
        self.done: list[Path] = []
        self.tag = uuid.uuid4().hex[:8]  # this bake's file names: an undone bake's files stay its own
        self.frame = scene.frame_current
        self.blur = scene.render.use_motion_blur
        for obj in objects:
            obj.modifiers.new(MODIFIER, "DISPLACE").strength = 0.0
        scene.render.use_motion_blur = True

    @property
    def progress(self) -> float:
        return len(self.done) / max(1, len(self.groups))

    def step(self) -> bool:
        """Export the next group; True when every group is written."""
        index = len(self.done)
        if index == len(self.groups):
            return True
        extension = FORMATS[self.fmt][0]
        path = self.folder / f"group_{index:02d}_{self.tag}{extension}"
        partial = path.with_name(f".{path.stem}.partial{extension}")
        self._check_space(index)
        group = bpy.data.collections.new(f".windgrass bake {index}")
        self.scene.collection.children.link(group)
        try:
            for obj in self.groups[index]:
                group.objects.link(obj)
            result = self._export(partial, group)
            if "FINISHED" not in result or not partial.is_file() or partial.stat().st_size == 0:
                raise BakeError(f"bake: Blender did not write the cache {path} ({result})")
            if self.fmt == "usd" and usd_finish.available():
                usd_finish.finish(partial, {object_path("usd", o): tuple(o.active_material.diffuse_color)[:3]
                                            for o in self.groups[index] if o.active_material is not None})
            os.replace(partial, path)
        except BaseException:
            self.cancel()
            raise
        finally:
            bpy.data.collections.remove(group)
            if partial.exists():
                partial.unlink()
        self.done.append(path)
        return len(self.done) == len(self.groups)

    def _check_space(self, index: int) -> None:
        """The disk still has room for group ``index`` (another writer may have filled it since the
        bake began: Blender's Alembic writer aborts on a full disk); else BakeError, and nothing of
        the bake is left."""
        need = estimate_bytes(self.item, self.first, self.last, self.groups[index])
        free = free_bytes(self.folder)
        if free is not None and need > free:
            self.cancel()
            raise BakeError(f"bake: the disk of {self.folder.parent} filled while baking: the next part needs about "
                            f"{need / 1e6:,.1f} MB and {free / 1e6:,.1f} MB are free; free some space and bake again "
                            "(nothing of this bake was kept)")

    def _export(self, path: Path, group) -> set:
        if self.fmt == "alembic":
            return bpy.ops.wm.alembic_export(
                filepath=str(path), start=self.first, end=self.last, selected=False, collection=group.name,
                flatten=True, uvs=True, normals=False, face_sets=False, export_hair=False,
                export_particles=False, as_background_job=False, init_scene_frame_range=False,
                evaluation_mode="RENDER")
        # USD writes the scene's frame range: the bake's for the export. The UV maps keep their
        # names (the materials read them); each material also as a UsdPreviewSurface.
        scene, kept = self.scene, (self.scene.frame_start, self.scene.frame_end)
        scene.frame_start, scene.frame_end = self.first, self.last
        options = dict(filepath=str(path), collection=group.name, selected_objects_only=False,
                       export_animation=True, evaluation_mode="RENDER", export_uvmaps=True, rename_uvmaps=False,
                       export_normals=False, export_materials=True, generate_preview_surface=True,
                       export_hair=False, export_lights=False, export_cameras=False, relative_paths=True,
                       export_textures_mode="NEW", export_textures=True)  # (the first is 4.3+'s, the second 4.2's)
        known = {p.identifier for p in bpy.ops.wm.usd_export.get_rna_type().properties}
        try:
            return bpy.ops.wm.usd_export(**{k: v for k, v in options.items() if k in known})
        finally:
            scene.frame_start, scene.frame_end = kept

    def _restore(self) -> None:
        self.scene.render.use_motion_blur = self.blur
        for objects in self.groups:
            for obj in objects:
                modifier = obj.modifiers.get(MODIFIER)
                if modifier is not None:
                    obj.modifiers.remove(modifier)

    def cancel(self) -> None:
        """Stop: the files written so far are deleted and the field stays live."""
        self._restore()
        self.abandon()
        self.scene.frame_set(self.frame)

    def abandon(self) -> None:
        """Delete the files written so far, touching no Blender data (the scene may be gone:
        an undo during the bake); empty folders go too."""
        for path in self.done:
            path.unlink(missing_ok=True)
        self.done.clear()
        _remove_empty(self.folder)

    def finish(self) -> Path:
        """Play the field from the written files (after the last ``step``); returns the folder."""
        while not self.step():
            pass
        seen = self._sees_grass()
        self._restore()
        caches = []
        for path, objects in zip(self.done, self.groups):
            bpy.ops.cachefile.open(filepath=str(path))
            cache = bpy.data.cache_files[-1]
            cache.filepath = bpy.path.relpath(str(path))
            cache["wg_uid"] = self.item.collection.get("wg_uid", "")
            caches.append(cache.name)
            play_in_a_loop(cache, self.first, self.last, self._loop_frames())
            for obj in objects:
                for heads_modifier in [m for m in obj.modifiers if m.type == "NODES" and m.name == heads.MODIFIER]:
                    # (a baked slot plays its cache alone: the flower heads' Geometry Nodes with
                    # a Mesh Sequence Cache crashed Blender 5.3 at the next frame change)
                    obj.modifiers.remove(heads_modifier)
                modifier = obj.modifiers.new(MODIFIER, "MESH_SEQUENCE_CACHE")
                modifier.cache_file = cache
                modifier.object_path = object_path(self.fmt, obj)
                modifier.use_vertex_interpolation = True  # motion-blur steps between the baked frames
            field_scene.leave_out_of_files([*objects, *(obj.data for obj in objects)], out=False)  # (saved now)
        self.item[RECORD] = {"folder": bpy.path.relpath(str(self.folder)), "first": self.first, "last": self.last,
                             "digest": self.digest, "camera": camera_fingerprint(self.scene), "caches": caches,
                             "tag": self.tag, "format": self.fmt, "seen": seen}
        self.scene.frame_set(self.frame)
        return self.folder

    def _loop_frames(self) -> int:
        """The field's loop in frames (``loop.py``; 0: none)."""
        from .properties import params_from_settings

        return loop.loop_frames(params_from_settings(self.item, self.scene))

    def _sees_grass(self) -> bool:
        """Whether the camera saw any of the field's grass (blades or cards) at the range's first,
        middle or last frame: a bake of none holds a still, empty field."""
        for frame in sorted({self.first, (self.first + self.last) // 2, self.last}):
            self.scene.frame_set(frame)
            rt = REGISTRY.built(key_of(self.scene, self.item))
            if rt is not None and any(len(pool.blocks) for pool in rt.pools.values()):
                return True
        return False


def play_in_a_loop(cache, first: int, last: int, period: int) -> bool:
    """A bake of a looping field (``simulation.loop``) that holds a whole loop from ``first`` plays
    it round and round: the cache's frame is keyed from ``first`` to ``first + period`` and repeated
    by a Cycles modifier (animation data, no driver: a farm node runs no script for it). Returns
    whether it does."""
    if not period or last - first + 1 < period:
        return False
    cache.override_frame = True
    for frame in (first, first + period):
        cache.frame = float(frame)
        cache.keyframe_insert("frame", frame=frame)
    curve = next(c for c in animation.action_fcurves(cache.animation_data) if c.data_path == "frame")
    for point in curve.keyframe_points:
        point.interpolation = "LINEAR"
    curve.modifiers.new("CYCLES")
    return True


def bake_field(scene, item, first: int, last: int, digest: str, fmt: str = "alembic") -> Path:
    """Bake frames ``first``-``last`` in one go, one file (scripts); returns the cache folder."""
    return Baker(scene, item, first, last, digest, fmt=fmt).finish()


def free_bake(scene, item) -> bool:
    """Remove the bake's modifiers, cache datablocks and record; returns whether there was one.
    Its files stay until no file refers to them (``collect_garbage``), so an undo brings the bake
    back whole. The runtime then writes the field live again (``runtime.free_bake``)."""
    record = item.get(RECORD)
    if record is None:
        return False
    for obj in _slots(item):
        modifier = obj.modifiers.get(MODIFIER)
        if modifier is not None:
            obj.modifiers.remove(modifier)
        field_scene.leave_out_of_files((obj, obj.data))  # (live again: made again on load)
    caches = [bpy.data.cache_files.get(name) for name in record.get("caches", ())]
    caches = [c for c in caches if c is not None]
    if caches:
        bpy.data.batch_remove(caches)  # (bpy.data.cache_files has no remove)
    del item[RECORD]
    return True


def record_files(item) -> list[Path]:
    """The cache files a field's bake plays (absolute paths; its cache datablocks' files)."""
    record = item.get(RECORD)
    if record is None:
        return []
    files = []
    for name in record.get("caches", ()):
        cache = bpy.data.cache_files.get(name)
        if cache is not None:
            files.append(Path(bpy.path.abspath(cache.filepath)).resolve())
    return files


def files_present(item) -> bool:
    """Whether every file the field's bake plays is on disk (and it has some)."""
    files = record_files(item)
    return bool(files) and all(f.is_file() for f in files)


def referenced_files() -> set[Path]:
    """Every cache file a bake of this file refers to."""
    return {f for s in bpy.data.scenes for item in owned.scene_fields(s)
            for f in record_files(item)}


def bake_root() -> Path | None:
    """``<blend folder>/<blend name>_windgrass`` of the open file (None when it is not saved)."""
    if not bpy.data.filepath:
        return None
    blend = Path(bpy.data.filepath)
    return (blend.parent / f"{blend.stem}_windgrass").resolve()


def collect_garbage(root: Path | None, keep: set[Path]) -> list[Path]:
    """Delete the bake files under ``root`` (``<field>/group_*.abc`` or ``.usdc`` and partial files) that are
    not in ``keep``, then the folders left empty; returns what was deleted. Plain files only: it
    runs at exit too, when Blender's data may be gone."""
    if root is None or not Path(root).is_dir():
        return []
    gone = []
    for folder in [f for f in Path(root).iterdir() if f.is_dir()]:
        for path in [f for ext, *_ in FORMATS.values() for f in (*folder.glob(f"group_*{ext}"),
                                                                  *folder.glob(f".group_*.partial{ext}"))]:
            if path.resolve() not in keep:
                path.unlink(missing_ok=True)
                gone.append(path)
        _remove_empty(folder)
    return gone


def _remove_empty(folder: Path) -> None:
    """The field's folder, then ``<blend>_windgrass``, when they hold nothing; the card atlas a USD
    bake writes beside its files (``textures/``) goes first when no USD file is left to read it."""
    textures = Path(folder) / "textures"
    if textures.is_dir() and not any(Path(folder).glob("group_*.usdc")):
        shutil.rmtree(textures, ignore_errors=True)
    for empty in (Path(folder), Path(folder).parent):
        if empty.is_dir() and not any(empty.iterdir()):
            empty.rmdir()


def status(scene, item, digest: str | None) -> str | None:
    """``digest``: of the field's parameters now (None: unknown, e.g. a setting out of range)."""
    record = item.get(RECORD)
    if record is None:
        return None
    text = f"Baked frames {record['first']}-{record['last']}: what the scene camera saw"
    if not files_present(item):
        return (f"Baked frames {record['first']}-{record['last']}, but its cache files are missing "
                f"({record.get('folder', '')}); the grass plays live: bake again or free the bake")
    stale = []
    if digest is not None and digest != record.get("digest"):
        stale.append("parameters changed")
    if camera_fingerprint(scene) != record.get("camera"):
        stale.append("camera changed")
    return text + (f"; stale: {', '.join(stale)} since (bake again)" if stale else "")


def cache_size(folder: Path) -> int:
    """Bytes of the cache files of a bake (Alembic or USD)."""
    return sum(f.stat().st_size for ext, *_ in FORMATS.values() for f in Path(folder).glob(f"*{ext}"))


def plays_cache(item) -> bool:
    """Whether the field plays its bake (baked, and its files are on disk; else it plays live)."""
    return is_baked(item) and files_present(item)
