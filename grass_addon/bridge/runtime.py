"""A grass field in Blender, frame by frame: resolving, building and the frame handlers.

Each field is resolved once into a ``FieldRuntime``: its parameters (with the scene's clock), the
numpy engine (``GrassField``), its terrain samples and its two slot pools (``pools.SlotPool``).
``registry.REGISTRY`` holds them. One frame is one pass (``update_field``): wind, solver and
shared cell data (``GrassField.seek``), LOD from the scene camera (eqs 7-11), slot assignment
(``slots.py``), vertex writes (``pools.py``). No ``bpy.ops``, no per-blade Python loop.

What rebuilds what:
  * an edit of the field's settings (``mark_dirty``; at once in scripts and background renders,
    once the edits settle in the UI), Rebuild, Add, file load: ``build_field`` resolves the field
    again and, when the objects' topology changed, rebuilds the objects (``scene.build_slots``);
  * a frame handler never creates or deletes objects. It resolves the engine again (numpy only)
    when the scene's clock or the animated wind changed; a field whose objects do not match its
    settings (an edit still settling) keeps drawing the runtime it has until the edit is applied.

Handlers (all ``@persistent``, added once by ``register``):
  ``frame_change_pre``       simulate and write the new frame;
  ``frame_change_post``      redo the LOD if the camera moved during evaluation (animated camera);
  ``depsgraph_update_post``  the same when the camera is moved without a frame change;
  ``load_post``              empty the registry; ``undo_post``/``redo_post`` forget slot state.
Which position shows which block is a function of the frame and camera alone (canonical order),
so frames rendered apart equal frames rendered in one run.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from .. import schema, slots
from ..errors import WindgrassError
from ..field import GrassField
from . import animation, bake, pools, properties
from . import camera as field_camera
from . import scene as field_scene
from .registry import REGISTRY, Key, key_of, warn_once

# Edits in the UI arrive once per slider step; they are coalesced and applied once the user pauses
# for this long, so dragging a slider on a large field does not re-simulate at every step.
EDIT_SETTLE_S = 0.15


@dataclass(eq=False)
class FieldRuntime:
    """One field resolved from its settings: everything a frame needs, nothing read again."""

    key: Key
    params: schema.Params  # validated, with the scene's clock
    digest: str  # of the parameters, the animated wind and the terrain samples
    clock: tuple[int, int, int]  # the scene's fps, frame_start, frame_end it was resolved with
    wind_fingerprint: str  # of the animated wind's F-curves ("" when not animated)
    wind_keys: tuple | None
    terrain_key: str
    heightfield: object  # terrain.Heightfield or None (flat ground)
    terrain_centre: tuple | None  # world XY the field is centred on over a terrain
    field: GrassField
    blades: pools.SlotPool
    cards: pools.SlotPool
    topology: str  # slots.topology_key: what the slot objects must be built for
    dirty: bool = False  # the settings were edited since: resolve again
    frame: int | None = None  # the frame last written
    subframe: float = 0.0  # and its sub-frame (motion-blur steps)
    lod: object = None  # its LOD weights
    camera_signature: tuple | None = None
    error: str | None = None  # why the field cannot be simulated now (its grass is hidden)


def get_runtime(scene, item) -> FieldRuntime | None:
    return REGISTRY.fields.get(key_of(scene, item))


def field_error(scene, item) -> str | None:
    """Why the field cannot be simulated now (a setting out of range, ...), or None."""
    return REGISTRY.errors.get(key_of(scene, item))


def _clock(scene) -> tuple[int, int, int]:
    return int(scene.render.fps), int(scene.frame_start), int(scene.frame_end)


# --------------------------------------------------------------------------------------------
# Resolving


def _wind_curves(scene, item, params) -> tuple[dict, str]:
    """The field's animated wind F-curves ({} when none) and their fingerprint."""
    fcurves = animation.wind_fcurves(scene, item) if scene.animation_data is not None else {}
    if not fcurves:
        return {}, ""
    return fcurves, animation.fingerprint(fcurves, animation.sample_range(scene, params))


def _wind(scene, item, params, previous: FieldRuntime | None):
    """(params without the animated values, wind keys, fingerprint) of the field's wind now."""
    fcurves, fingerprint = _wind_curves(scene, item, params)
    if not fcurves:
        return params, None, ""
    # The animated values change every frame; the keys carry them, so the parameters must not.
    stable = params.replace({f"wind.{role}": schema.BY_NAME[f"wind.{role}"].default for role in fcurves})
    if previous is not None and previous.wind_fingerprint == fingerprint:
        return stable, previous.wind_keys, fingerprint
    frames = animation.sample_range(scene, params)
    return stable, animation.sample_wind_keys(fcurves, params, frames), fingerprint


def resolve(scene, item) -> FieldRuntime:
    """The field's runtime for its settings now: the registered one when nothing it depends on
    changed, else a new one (the engine is rebuilt; the terrain re-sampled only when its object
    or grid changed). Never touches the field's objects; raises WindgrassError on bad settings."""
    key = key_of(scene, item)
    previous = REGISTRY.fields.get(key)
    if previous is None:
        REGISTRY.forget_missing({key_of(s, f) for s in bpy.data.scenes if hasattr(s, "windgrass")
                                 for f in s.windgrass.fields})
    params, wind_keys, fingerprint = _wind(scene, item, properties.params_from_settings(item, scene), previous)
    t_key = field_scene.terrain_key(scene, item, params)
    if previous is not None and previous.terrain_key == t_key:
        heightfield, centre = previous.heightfield, previous.terrain_centre
    else:
        heightfield, centre = field_scene.sample_terrain(scene, item, params)
    digest = hashlib.sha1((params.digest() + fingerprint
                           + (heightfield.fingerprint() if heightfield is not None else "")).encode()).hexdigest()
    if previous is not None and previous.digest == digest:
        previous.dirty = False
        previous.clock = _clock(scene)
        return previous
    field = GrassField(params, wind_keys=wind_keys, terrain=heightfield)
    field.sim.progress = _seek_progress(item.name)
    blade_shape, card_shape = slots.pool_shapes(field.layout, params)
    rt = FieldRuntime(key=key, params=params, digest=digest, clock=_clock(scene), wind_fingerprint=fingerprint,
                      wind_keys=wind_keys, terrain_key=t_key, heightfield=heightfield, terrain_centre=centre,
                      field=field, blades=pools.blade_pool(field, blade_shape),
                      cards=pools.card_pool(field, card_shape),
                      topology=slots.topology_key(field.layout, params))
    REGISTRY.fields[key] = rt
    if item.collection is not None:
        field_scene.update_field_materials(item, params, scene)
    return rt


def _seek_progress(name: str):
    """A long seek reports itself: a line a second in scripts and background renders, the
    progress cursor in the UI."""
    def report(done: int, total: int) -> None:
        if bpy.app.background:
            print(f"Windgrass: simulating '{name}': {done}/{total} frames", flush=True)
            return
        wm = bpy.context.window_manager
        if done >= total:
            wm.progress_end()
        else:
            wm.progress_begin(0, total)
            wm.progress_update(done)

    return report


def _current(scene, item) -> FieldRuntime:
    """The runtime a frame handler uses: the registered one unless the scene's clock or the
    animated wind changed under it (then resolved again, numpy only) or there is none yet."""
    rt = REGISTRY.fields.get(key_of(scene, item))
    if rt is None:
        return resolve(scene, item)
    if rt.dirty:  # an edit is settling: its update (not a frame handler) applies it
        return rt
    if rt.clock != _clock(scene) or _wind_curves(scene, item, rt.params)[1] != rt.wind_fingerprint:
        return resolve(scene, item)
    if rt.terrain_key and field_scene.terrain_key(scene, item, rt.params) != rt.terrain_key:
        warn_once(f"the terrain of field '{item.name}' is gone or changed; the grass keeps the ground it "
                  "was built on until Rebuild (on flat ground without a terrain)")
    return rt


# --------------------------------------------------------------------------------------------
# Building and removing (operators, edits, scripts: never from a frame handler)


def build_field(scene, item, force: bool = False) -> bpy.types.Collection:
    """Resolve the field and (re)build its objects when their topology changed (always with
    ``force``: Rebuild, which also re-samples the terrain and frees a bake), then write the
    current frame. A baked field is left as baked (an edit makes its bake stale, see bake.status)."""
    if bake.is_baked(item):
        if not force:
            return item.collection
        bake.free_bake(scene, item)
    if getattr(item, "terrain", None) is not None:
        try:  # the terrain's matrix and modifiers as they are now
            bpy.context.view_layer.update()
        except Exception:
            pass
    field_scene.separate_copy(item)
    if force:
        reset_field(scene, item)
    rt = resolve(scene, item)
    coll = item.collection
    if force or coll is None or coll.get("wg_topology") != rt.topology:
        coll = field_scene.build_slots(scene, item, rt.field.layout, rt.params, rt.terrain_centre, rt.topology)
        rt.blades.state.forget()
        rt.cards.state.forget()
    # The frame handler edits meshes while a render runs: keep the interface locked then.
    scene.render.use_lock_interface = True
    _write(scene, item, rt)
    write_read_me()
    return coll


def start_bake(scene, item, first: int, last: int, groups: int = 1) -> bake.Baker:
    """A bake of frames ``first``-``last`` of the field in ``groups`` steps, ready to step
    (``bake.Baker``); BakeError or ParameterError on what prevents it."""
    properties.params_from_settings(item, scene)  # a setting out of range stops here, named
    if bake.is_baked(item):
        free_bake(scene, item)
    rt = resolve(scene, item)
    if item.collection is None or item.collection.get("wg_topology") != rt.topology:
        build_field(scene, item)
    return bake.Baker(scene, item, first, last, params_digest(scene, item), groups)


def bake_field(scene, item, first: int, last: int):
    """Bake frames ``first``-``last`` of the field into Alembic caches beside the .blend and play
    the field from them (``bake.py``); returns the cache folder."""
    folder = start_bake(scene, item, first, last).finish()
    write_read_me()
    return folder


def free_bake(scene, item) -> None:
    """Back to the live simulation."""
    if bake.free_bake(scene, item):
        build_field(scene, item)
    write_read_me()


def bake_status(scene, item) -> str | None:
    """What the field's bake holds and whether it is stale (None: live)."""
    return bake.status(scene, item, params_digest(scene, item)) if bake.is_baked(item) else None


def params_digest(scene, item) -> str | None:
    """Digest of the field's settings now (None when a setting is out of range)."""
    try:
        return properties.params_from_settings(item, scene).digest()
    except WindgrassError:
        return None


READ_ME = "Windgrass - read me"


def write_read_me() -> None:
    """A text block that says, in a Blender without Windgrass, what the grass needs."""
    live, baked = [], []
    for s in bpy.data.scenes:
        for item in getattr(s, "windgrass", None).fields if hasattr(s, "windgrass") else ():
            (baked if bake.is_baked(item) else live).append(f"{s.name} / {item.name}")
    text = bpy.data.texts.get(READ_ME) or bpy.data.texts.new(READ_ME)
    lines = ["This file has grass fields of the Windgrass extension for Blender.", ""]
    if live:
        lines += ["Live fields: their grass is simulated by the Windgrass add-on every frame. Without the",
                  "add-on they stay frozen at the last pose written. Install Windgrass, or bake them",
                  "(Grass tab > Bake) to play and render them in any Blender:"] + [f"  {n}" for n in live] + [""]
    if baked:
        lines += ["Baked fields: they play an Alembic cache beside this file (folder <file>_windgrass)",
                  "in any Blender; keep that folder with the file:"] + [f"  {n}" for n in baked]
    text.from_string("\n".join(lines) + "\n")


def remove_field(scene, item) -> None:
    """Delete everything the field made (``scene.remove_datablocks``, its bake) and forget its
    runtime."""
    reset_field(scene, item)
    bake.free_bake(scene, item)
    field_scene.remove_datablocks(item)


def reset_field(scene, item) -> None:
    """Forget the runtime of ``item``: the next update resolves it from its settings again."""
    key = key_of(scene, item)
    REGISTRY.fields.pop(key, None)
    REGISTRY.errors.pop(key, None)


# --------------------------------------------------------------------------------------------
# One frame


def _write(scene, item, rt: FieldRuntime, depsgraph=None) -> None:
    """wind -> solver -> cell data (seek), LOD from the camera, slot pools, writes.

    With the scene's motion blur on, or at a sub-frame (Blender evaluates frame + subframe for
    each motion-blur step), the vertices are those of that instant and carry their velocity."""
    frame, subframe = scene.frame_current, float(scene.frame_subframe)
    camera = field_camera.field_camera(scene, item, depsgraph)
    rt.field.view(camera, frame)  # the window of blocks this camera needs (same window: no work)
    if camera is None and rt.field.notice:
        warn_once(f"field '{item.name}' has no camera to follow: {rt.field.notice}")
    if rt.frame != frame or rt.field.cells is None:
        rt.field.seek(frame)  # a camera-only update reuses this frame's cell data
    lod = rt.field.lod(camera)
    if camera is None:
        # No camera: every block is geometry (lod_weights(None)); the pools take the blocks
        # nearest the field centre.
        bounds = rt.field.layout.block_bounds
        centre = 0.5 * (bounds[:, :2] + bounds[:, 2:])
        block_distance = np.hypot(centre[:, 0], centre[:, 1]).astype(np.float32)
    else:
        block_distance = np.asarray(lod.block_distance, dtype=np.float32)
    motion = None
    if scene.render.use_motion_blur or subframe != 0.0:
        motion = (frame, subframe, float(rt.params.render.fps))
    rt.blades.write(item, rt.field, lod, block_distance, motion)
    rt.cards.write(item, rt.field, lod, block_distance, motion)
    rt.frame, rt.subframe, rt.lod = frame, subframe, lod
    rt.camera_signature = field_camera.signature(camera)


def update_field(scene, item, depsgraph=None, camera_moved_only: bool = False) -> FieldRuntime | None:
    """Write the field ``item`` of ``scene`` for ``scene.frame_current`` (a frame handler's work).
    Returns its runtime, or None when the field has no objects (not built, or deleted by hand).

    ``camera_moved_only``: skip the write when this frame was written with the same camera
    (the ``frame_change_post`` pass, see ``on_frame_change_post``)."""
    if item.collection is None:
        warn_once(f"field '{item.name}' has no collection (deleted?); nothing to update")
        return None
    if bake.is_baked(item):
        return None  # its objects play the cache
    if camera_moved_only:
        rt = get_runtime(scene, item)
        if rt is None or rt.frame != scene.frame_current or rt.subframe != float(scene.frame_subframe):
            return rt  # not written at this instant yet: the frame handlers will do it
        if rt.camera_signature == field_camera.signature(field_camera.field_camera(scene, item, depsgraph)):
            return rt  # same camera, same frame: nothing to do (cheap: no parameter read)
    rt = _current(scene, item)
    if item.collection.get("wg_topology") != rt.topology:
        if rt.dirty:
            return rt  # the edit that changed the objects' topology is still settling
        raise WindgrassError(f"the objects of field '{item.name}' do not match its settings; press Rebuild")
    _write(scene, item, rt, depsgraph)
    return rt


def update_scene(scene, depsgraph=None, camera_moved_only: bool = False) -> None:
    """Write every field of ``scene`` for its current frame; never raises into Blender."""
    settings = getattr(scene, "windgrass", None)
    if settings is None:
        return
    for item in settings.fields:
        _guarded(update_field, scene, item, depsgraph, camera_moved_only=camera_moved_only)


def _guarded(work, scene, item, *args, camera_moved_only: bool = False) -> None:
    """``work(scene, item, ...)``, never raising: a field that cannot be simulated (a setting
    out of range, a failure) records the error for the panel and for scripts (``field_error``)
    and hides its grass, so no frame shows the grass of another frame."""
    key = key_of(scene, item)
    try:
        if camera_moved_only:
            work(scene, item, *args, camera_moved_only=True)
        else:
            work(scene, item, *args)
    except Exception as exc:  # a handler must not break playback or rendering
        message = str(exc) if isinstance(exc, WindgrassError) else f"{type(exc).__name__}: {exc}"
        REGISTRY.errors[key] = message
        warn_once(f"field '{item.name}' cannot be simulated, its grass is hidden: {message}")
        try:
            _hide(scene, item)
        except Exception as hide_exc:  # pragma: no cover (objects gone mid-render)
            warn_once(f"field '{item.name}' could not be hidden: {hide_exc}")
        REGISTRY.fields.pop(key, None)  # resolved again (and checked again) at the next update
    else:
        if not camera_moved_only:  # (that pass skips fields not written at this frame)
            REGISTRY.errors.pop(key, None)


def _hide(scene, item) -> None:
    """Collapse every slot of the field to a point (nothing drawn) and forget what they showed."""
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.blades.collapse(item)
        rt.cards.collapse(item)
        rt.frame = None
        return
    for role in (field_scene.ROLE_BLADES, field_scene.ROLE_CARDS):
        pools.collapse_objects(field_scene.slot_objects(item, role).values())


# --------------------------------------------------------------------------------------------
# Edits


def mark_dirty(scene, item, defer: bool | None = None) -> None:
    """Settings of ``item`` changed: resolve and write it again (the digest decides what is
    rebuilt). Scripts and background renders (``bpy.app.background``) get the update at once; in
    the UI (``defer``) it waits until the edits settle (a timer), so interactive edits stay fluid.
    """
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.dirty = True
    if not (defer if defer is not None else not bpy.app.background):
        _apply_edit(scene, item)
        return
    REGISTRY.pending[key_of(scene, item)] = time.monotonic()
    if not bpy.app.timers.is_registered(_flush_pending):
        bpy.app.timers.register(_flush_pending, first_interval=EDIT_SETTLE_S)


def _apply_edit(scene, item) -> None:
    if item.collection is not None:
        _guarded(build_field, scene, item)


def _flush_pending() -> float | None:
    """Timer: apply settled edits; run again shortly while the user is still dragging."""
    latest = max(REGISTRY.pending.values(), default=0.0)
    wait = latest + EDIT_SETTLE_S - time.monotonic()
    if wait > 0:
        return wait
    pending = list(REGISTRY.pending)
    REGISTRY.pending.clear()
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    for scene_uid, uid in pending:
        scene = scenes.get(scene_uid)
        item = next((f for f in scene.windgrass.fields if f.uid == uid), None) if scene else None
        if item is not None:
            _apply_edit(scene, item)
    return None


# --------------------------------------------------------------------------------------------
# Handlers


@persistent
def on_frame_change_pre(scene, depsgraph=None):
    """Simulate and write the new frame."""
    update_scene(scene)


@persistent
def on_frame_change_post(scene, depsgraph=None):
    """Before evaluation (``_pre``) an animated or just-moved camera still has its old matrix.
    After evaluation the camera is where it is at this frame: redo the LOD (eqs 7-11) and the
    writes if it moved; Blender then evaluates the edited meshes in a second pass."""
    update_scene(scene, depsgraph, camera_moved_only=True)


@persistent
def on_depsgraph_update_post(scene, depsgraph=None):
    """The camera was moved in the viewport (no frame change): follow it with the LOD. Only
    fields already written at this frame are touched, and only when the camera moved, so the
    mesh edits made here (which trigger another update) end the chain at once."""
    if not REGISTRY.fields or bpy.app.is_job_running("RENDER"):
        return
    update_scene(scene, depsgraph, camera_moved_only=True)


@persistent
def on_load_post(*_args):
    """A new file: forget every runtime, and rebuild the objects of fields saved with another
    topology than their settings give now (files of earlier versions), here rather than in a
    frame handler."""
    REGISTRY.clear()
    for scene in bpy.data.scenes:
        for item in getattr(scene, "windgrass", None).fields if hasattr(scene, "windgrass") else ():
            if item.collection is not None and not bake.is_baked(item):
                _guarded(_rebuild_if_outdated, scene, item)


def _rebuild_if_outdated(scene, item) -> None:
    if item.collection.get("wg_topology") != resolve(scene, item).topology:
        build_field(scene, item)


@persistent
def on_undo_redo_post(*_args):
    """Undo and redo bring back older mesh data: forget what the slots show, so the next
    update rewrites every slot (positions and colours) instead of trusting stale state."""
    for rt in REGISTRY.fields.values():
        rt.blades.state.forget()
        rt.cards.state.forget()


_HANDLERS = (
    (bpy.app.handlers.frame_change_pre, on_frame_change_pre),
    (bpy.app.handlers.frame_change_post, on_frame_change_post),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update_post),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.undo_post, on_undo_redo_post),
    (bpy.app.handlers.redo_post, on_undo_redo_post),
)


def _same(a, b) -> bool:
    return getattr(a, "__name__", None) == b.__name__ and getattr(a, "__module__", None) == b.__module__


def register() -> None:
    """Add the handlers exactly once (also after a reload of the add-on); settings edits reach
    ``mark_dirty`` through ``properties.on_edit``."""
    for handlers, func in _HANDLERS:
        for existing in [h for h in handlers if _same(h, func)]:
            handlers.remove(existing)
        handlers.append(func)
    properties.on_edit = mark_dirty


def unregister() -> None:
    for handlers, func in _HANDLERS:
        for existing in [h for h in handlers if _same(h, func)]:
            handlers.remove(existing)
    if bpy.app.timers.is_registered(_flush_pending):
        bpy.app.timers.unregister(_flush_pending)
    properties.on_edit = None
    REGISTRY.clear()
