"""A grass field in Blender, frame by frame: settings, datablocks, the engine and the handlers.

Two kinds of work, kept apart because Blender's undo needs it:

* **Datablocks** (``apply_settings``): the field's collection, ground, slot objects, materials and
  card image for its settings. Blender's undo stores the whole file after each operator and each
  property edit and, on Ctrl+Z, reuses the datablocks it believes unchanged since the last step:
  a datablock added or deleted between steps (by a timer, a handler) leaves it pointers to freed
  memory, and Blender crashes. So datablocks change only inside the operator or the property edit
  that asked for it (``mark_dirty`` applies them at once), on file load, and never from a timer,
  a frame handler or an undo handler. Every undo step then holds objects that match its settings.
* **The engine** (``resolve``, numpy only) and **vertex writes** (``update_field``): each field is
  resolved into a ``FieldRuntime`` (its parameters with the scene's clock, the numpy engine
  ``GrassField``, its two slot pools); ``registry.REGISTRY`` holds them. One frame is one pass:
  wind, solver and shared cell data (``GrassField.seek``), LOD from the camera (eqs 7-11), slot
  assignment (``slots.py``), vertex writes (``pools.py``). No ``bpy.ops``, no per-blade Python
  loop. In the UI an edit's engine work waits until the edits settle (a timer), so dragging a
  slider stays fluid; undo and redo mark every runtime dirty and rewrite the current frame.

Handlers (all ``@persistent``, added once by ``register``):
  ``frame_change_pre``       simulate and write the new frame;
  ``frame_change_post``      redo the LOD if the camera moved during evaluation (animated camera);
  ``depsgraph_update_post``  the same when the camera is moved without a frame change;
  ``load_post``              empty the registry, bring outdated objects up to date;
  ``save_pre``/``save_post``  a live field is saved without its slot geometry (made again after);
  ``undo_post``/``redo_post`` the settings may be others now: resolve again, rewrite every slot.
Which position shows which block is a function of the frame and camera alone (canonical order),
so frames rendered apart equal frames rendered in one run.
"""

from __future__ import annotations

import atexit
import hashlib
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np
from bpy.app.handlers import persistent

from .. import forces, interaction, memory, schema
from .. import paint as paint_core
from ..errors import WindgrassError
from ..field import GrassField
from . import animation, bake, maps, materials, pools, properties, textures, tracks
from . import camera as field_camera
from . import scene as field_scene
from .registry import REGISTRY, Key, key_of, warn_once
from .scene import ROLE_BLADES, ROLE_CARDS

# Edits in the UI arrive once per slider step; they are coalesced and applied once the user pauses
# for this long, so dragging a slider on a large field does not re-simulate at every step.
EDIT_SETTLE_S = 0.15
# How often the viewport's views are looked at (orbiting changes no data, so no handler runs).
VIEW_POLL_S = 0.1
STROKE_GOAL_S = 0.5  # a field whose strokes take longer to show follows when paint mode is left
PAINT_MODE_POLL_S = 0.25


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
    paint: str = ""  # paint.fingerprint of the paint the engine grows
    paint_shown: str | None = None  # and of the one the ground and paint map show (update_paint_look)
    track: str = ""  # tracks.fingerprint of the stored collider motion the engine uses
    dirty: bool = False  # the settings were edited since: resolve again
    frame: int | None = None  # the frame last written
    subframe: float = 0.0  # and its sub-frame (motion-blur steps)
    lod: object = None  # its LOD weights
    camera_signature: tuple | None = None
    trail: object = False  # the trail map the far canopy shows (None: none; False: not yet set)
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


def terrain_of(scene, item, params, force: bool = False) -> tuple:
    """(heightfield, centre, key) of the field's terrain: sampled once and kept while the terrain
    object and the grid hold (``REGISTRY.terrains``); ``force`` (Rebuild) samples it again."""
    key = key_of(scene, item)
    t_key = field_scene.terrain_key(scene, item, params)
    kept = REGISTRY.terrains.get(key)
    if not force and kept is not None and kept[0] == t_key:
        return kept[1], kept[2], t_key
    heightfield, centre = field_scene.sample_terrain(scene, item, params)
    REGISTRY.terrains[key] = (t_key, heightfield, centre)
    return heightfield, centre, t_key


def paint_of(scene, item, params):
    """The field's paint (``maps.paint_of``), read again only when its settings, its terrain or
    keep-out collection, or one of the datablocks it reads changed since (``REGISTRY.strokes``,
    counted by ``on_depsgraph_update_post``)."""
    key = key_of(scene, item)
    coll = getattr(item, "keep_out_collection", None)
    outline = [] if coll is None else sorted((o.name, [round(v, 6) for row in o.matrix_world for v in row])
                                             for o in coll.all_objects)
    signature = (tuple(maps.sources(params)), tuple(params.paint.extent), params.to_dict()["keep_out"],
                 field_scene.terrain_key(scene, item, params), getattr(coll, "name", ""), outline,
                 REGISTRY.strokes.get(key, 0), _ground_matrix(item))
    kept = REGISTRY.paints.get(key)
    if kept is not None and kept[0] == signature:
        return kept[1]
    paint = maps.paint_of(scene, item, params)
    REGISTRY.paints[key] = (signature, paint)
    REGISTRY.paint_deps[key] = maps.depends_on(scene, item, params)
    return paint


def _ground_matrix(item) -> tuple:
    ground = field_scene.ground_object(item)
    return () if ground is None else tuple(round(v, 6) for row in ground.matrix_world for v in row)


def topology_of(params, heightfield, item) -> str:
    """What the field's objects must be built for (``scene.topology``)."""
    return field_scene.topology(params, heightfield, field_scene.painted_settings(params, item))


def resolve(scene, item) -> FieldRuntime:
    """The field's runtime for its settings now: the registered one when nothing it depends on
    changed, else a new one (the engine is rebuilt). Numpy only: never touches a datablock
    (``apply_settings`` does); raises WindgrassError on bad settings."""
    key = key_of(scene, item)
    previous = REGISTRY.fields.get(key)
    if previous is None:
        REGISTRY.forget_missing({key_of(s, f) for s in bpy.data.scenes if hasattr(s, "windgrass")
                                 for f in s.windgrass.fields})
    params, wind_keys, fingerprint = _wind(scene, item, properties.params_from_settings(item, scene), previous)
    heightfield, centre, t_key = terrain_of(scene, item, params)
    topology = topology_of(params, heightfield, item)  # (a keep-out collection is not a setting)
    tracks.collider_objects(item), tracks.effector_objects(item)  # a bad collection is named here
    colliders, effectors, track = tracks.stored(item)
    colliders = colliders + interaction.colliders_from_params(params)  # (a scene file's, in headless renders)
    effectors = forces.join(effectors, forces.effectors_from_params(params))
    digest = hashlib.sha1((params.digest() + fingerprint + topology + tracks.effector_digest(item)
                           + (heightfield.fingerprint() if heightfield is not None else "")).encode()).hexdigest()
    paint = paint_of(scene, item, params)
    painted = paint_core.fingerprint(paint)
    if previous is not None and previous.digest == digest:
        if previous.track != track:  # the colliders moved: the wind's simulation stays
            previous.field.set_interaction(colliders, previous.field.effectors)
            previous.track, previous.frame = track, None
        if previous.paint != painted:  # a stroke: make again only the blocks it touched
            started = time.perf_counter()
            made = previous.field.repaint(paint, frame=scene.frame_current)
            previous.paint, previous.frame = painted, None
            REGISTRY.last_repaint = (time.perf_counter() - started, made)
        previous.dirty = False
        previous.clock = _clock(scene)
        return previous
    field = GrassField(params, wind_keys=wind_keys, terrain=heightfield, paint=paint, colliders=colliders,
                       effectors=effectors)
    field.sim.progress = _seek_progress(item.name)
    rt = FieldRuntime(key=key, params=params, digest=digest, clock=_clock(scene), wind_fingerprint=fingerprint,
                      wind_keys=wind_keys, terrain_key=t_key, heightfield=heightfield, terrain_centre=centre,
                      field=field, blades=pools.SlotPool(ROLE_BLADES, field.shapes[ROLE_BLADES]),
                      cards=pools.SlotPool(ROLE_CARDS, field.shapes[ROLE_CARDS]), topology=topology,
                      paint=painted, track=track)
    REGISTRY.fields[key] = rt
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
    """The runtime a frame handler uses: the registered one unless its settings may have changed
    (an edit, undo), the scene's clock or the animated wind changed under it (then resolved
    again, numpy only), or there is none yet."""
    rt = REGISTRY.fields.get(key_of(scene, item))
    if rt is None or rt.dirty:
        return resolve(scene, item)
    if rt.clock != _clock(scene) or _wind_curves(scene, item, rt.params)[1] != rt.wind_fingerprint:
        return resolve(scene, item)
    if rt.terrain_key and field_scene.terrain_key(scene, item, rt.params) != rt.terrain_key:
        warn_once(f"the terrain of field '{item.name}' is gone or changed; the grass keeps the ground it "
                  "was built on until Rebuild (on flat ground without a terrain)")
    return rt


# --------------------------------------------------------------------------------------------
# Datablocks: only inside operators, property edits and file load (see the module docstring)


def apply_settings(scene, item, force: bool = False) -> None:
    """Bring the field's datablocks to its settings now: the objects are rebuilt when their
    topology changed (always with ``force``: Rebuild, which also re-samples the terrain and frees
    a bake), the materials' values refreshed. A baked field is left as baked (an edit makes its
    bake stale, see bake.status); a field without objects (never built, deleted by hand) gets
    none. Raises WindgrassError on bad settings (nothing is changed then)."""
    if bake.is_baked(item):
        if not force:
            return
        bake.free_bake(scene, item)
    if item.collection is None and not force:
        return
    params = properties.params_from_settings(item, scene)
    memory.check(params)  # before anything is built: a card range that would run out of memory
    if force and getattr(item, "terrain", None) is not None:
        try:  # the terrain's matrix and modifiers as they are now
            bpy.context.view_layer.update()
        except Exception:
            pass
    heightfield, centre, _ = terrain_of(scene, item, params, force=force)
    field_scene.separate_copy(item)
    coll = item.collection
    if force or coll is None or coll.get(field_scene.TOPOLOGY) != topology_of(params, heightfield, item):
        field_scene.build_slots(scene, item, params, heightfield, centre)
        _forget_slots(scene, item, dirty=True)
    else:
        if field_scene.fill_slots(item, params):  # a file saved with empty slots (on_save_pre)
            _forget_slots(scene, item)
        field_scene.update_field_materials(item, params, scene)
    # The frame handler edits meshes while a render runs: keep the interface locked then.
    if not scene.render.use_lock_interface:
        scene.render.use_lock_interface = True


def _forget_slots(scene, item, dirty: bool = False) -> None:
    """The field's slot meshes hold something else now: its pools write every slot next time."""
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.dirty = rt.dirty or dirty
        rt.blades.state.forget()
        rt.cards.state.forget()


def build_field(scene, item, force: bool = False) -> bpy.types.Collection:
    """Add, Rebuild (``force``), scripts: the field's datablocks for its settings and its current
    frame written at once (``apply_settings``, ``update_field``)."""
    if bake.is_baked(item) and not force:
        return item.collection
    apply_settings(scene, item, force=True if item.collection is None else force)
    if force:
        reset_field(scene, item)
    update_field(scene, item)
    write_read_me()
    return item.collection


def start_bake(scene, item, first: int, last: int, groups: int = 1) -> bake.Baker:
    """A bake of frames ``first``-``last`` of the field in ``groups`` steps, ready to step
    (``bake.Baker``); BakeError or ParameterError on what prevents it."""
    properties.params_from_settings(item, scene)  # a setting out of range stops here, named
    if bake.is_baked(item):
        free_bake(scene, item)
    rt = resolve(scene, item)
    if item.collection is None or item.collection.get(field_scene.TOPOLOGY) != rt.topology:
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
    """Digest of the field's settings and paint now (None when a setting is out of range)."""
    try:
        digest = properties.params_from_settings(item, scene).digest()
    except WindgrassError:
        return None
    kept = REGISTRY.paints.get(key_of(scene, item))
    painted = paint_core.fingerprint(kept[1]) if kept is not None else ""
    return f"{digest}|{painted}" if painted else digest


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
        lines += ["Live fields: their grass is made and simulated by the Windgrass add-on every frame (the",
                  "file keeps their settings, not their blades). Without the add-on they show only their",
                  "ground. Install Windgrass, or bake them (Grass tab > Bake) to play and render them in any",
                  "Blender:"] + [f"  {n}" for n in live] + [""]
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


def _write(scene, item, rt: FieldRuntime, depsgraph=None, views=None) -> None:
    """The frame as the engine computes it (``GrassField.frame``: wind, solver, cell data, LOD
    from the views, each role's blocks and vertices, gust offset, trail map), written: the views
    are ``camera.field_views`` (the scene camera in renders, the 3D views in the viewport).

    With the scene's motion blur on, or at a sub-frame (Blender evaluates frame + subframe for
    each motion-blur step), the vertices are those of that instant and carry their velocity."""
    if views is None:
        views = field_camera.field_views(scene, item, depsgraph)
    shown = rt.field.frame(scene.frame_current, float(scene.frame_subframe), views,
                           blur=bool(scene.render.use_motion_blur))
    if not views and rt.field.notice:
        warn_once(f"field '{item.name}' has no camera to follow: {rt.field.notice}")
    rt.blades.write(item, shown.blades)
    rt.cards.write(item, shown.cards)
    if shown.gust is not None:  # the far grass's gust waves travel with the mean wind
        reg = field_scene.registered(item)
        materials.set_gust_offset(shown.gust[0], shown.gust[1], rt.params, reg.get(field_scene.ROLE_CARD_MATERIAL),
                                  reg.get(field_scene.ROLE_CANOPY_MATERIAL))
    _write_trails(item, rt, shown.trail)
    rt.frame, rt.subframe, rt.lod = shown.frame, shown.subframe, shown.lod
    rt.camera_signature = field_camera.signature(views)


def _write_trails(item, rt: FieldRuntime, trail) -> None:
    """The far canopy's trampled trails (``interaction.trail_map``, or None): its image and
    mapping, written when they changed."""
    if trail is None and rt.trail is None:
        return
    reg = field_scene.registered(item)
    image = reg.get(field_scene.ROLE_TRAIL_IMAGE)
    if trail is not None and isinstance(image, bpy.types.Image):
        if not rt.trail or rt.trail.extent != trail.extent or not np.array_equal(rt.trail.flat, trail.flat):
            textures.write_trail_image(image, trail.flat)
    materials.set_trail(reg.get(field_scene.ROLE_CANOPY_MATERIAL), trail)
    rt.trail = trail


def update_field(scene, item, depsgraph=None, camera_moved_only: bool = False) -> FieldRuntime | None:
    """Write the field ``item`` of ``scene`` for ``scene.frame_current`` (a frame handler's work).
    Returns its runtime, or None when the field has no objects (not built, or deleted by hand).

    ``camera_moved_only``: skip the write when this frame was written with the same camera
    (the ``frame_change_post`` pass, see ``on_frame_change_post``)."""
    if item.collection is None:
        warn_once(f"field '{item.name}' has no collection (deleted?); nothing to update")
        return None
    if plays_cache(item):
        return None  # its objects play the cache
    views = None
    if camera_moved_only:
        rt = get_runtime(scene, item)
        if rt is None or rt.frame != scene.frame_current or rt.subframe != float(scene.frame_subframe):
            return rt  # not written at this instant yet: the frame handlers will do it
        views = field_camera.field_views(scene, item, depsgraph)
        if rt.camera_signature == field_camera.signature(views):
            return rt  # same views, same frame: nothing to do (cheap: no parameter read)
    rt = _current(scene, item)
    if item.collection.get(field_scene.TOPOLOGY) != rt.topology:
        # Windgrass rebuilds the objects whenever the settings ask for it (apply_settings); only a
        # change made around it (objects edited by hand, settings written as raw ID properties)
        # gets here, and a frame handler must not add or delete datablocks.
        raise WindgrassError(f"the objects of field '{item.name}' were not built for its settings "
                             "(changed outside Windgrass); press Rebuild")
    if rt.paint_shown != rt.paint:
        field_scene.update_paint_look(item, rt.params, rt.field.cache.paint)
        rt.paint_shown = rt.paint
    _write(scene, item, rt, depsgraph, views)
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
        if not isinstance(exc, WindgrassError):  # a fault of Windgrass, not a setting: its trace for a report
            traceback.print_exc()
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
    """Settings of ``item`` changed (a property edit, an operator): its datablocks follow at once
    (``apply_settings``: the undo step Blender pushes after the edit holds objects that match),
    then the engine is resolved again and the frame written (the digest decides what is rebuilt).
    Scripts and background renders (``bpy.app.background``) get the engine's update at once; in
    the UI (``defer``) it waits until the edits settle (a timer), so dragging a slider stays fluid.
    """
    if item.collection is None or bake.is_baked(item):
        return
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.dirty = True
    _guarded(apply_settings, scene, item)
    if getattr(item, "collider_collection", None) is not None or getattr(item, "effector_collection", None) \
            is not None or tracks.TRACK_KEY in item.collection:
        REGISTRY.motion.add(key_of(scene, item))
    if not (defer if defer is not None else not bpy.app.background):
        if key_of(scene, item) in REGISTRY.motion:
            REGISTRY.motion.discard(key_of(scene, item))
            _guarded(update_track, scene, item)
        _guarded(update_field, scene, item)
        return
    _refresh_later([key_of(scene, item)])


def _refresh_later(keys) -> None:
    """Write these fields' current frame once the edits settle (a timer: numpy and vertex writes
    only, no datablock is added or removed there)."""
    now = time.monotonic()
    for key in keys:
        REGISTRY.pending[key] = now
    if not bpy.app.timers.is_registered(_flush_pending):
        bpy.app.timers.register(_flush_pending, first_interval=EDIT_SETTLE_S)


def _flush_pending() -> float | None:
    """Timer: write the fields whose edits settled; run again shortly while the user is still
    dragging. A field whose strokes take longer than STROKE_GOAL_S to show (a large field) waits
    while its terrain is in a paint mode: it follows when the artist leaves it."""
    latest = max(REGISTRY.pending.values(), default=0.0)
    wait = latest + EDIT_SETTLE_S - time.monotonic()
    if wait > 0:
        return wait
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    waiting = False
    for key in list(REGISTRY.pending):
        scene = scenes.get(key[0])
        item = next((f for f in scene.windgrass.fields if f.uid == key[1]), None) if scene else None
        if item is None or item.collection is None:
            del REGISTRY.pending[key]
            continue
        if REGISTRY.stroke_s.get(key, 0.0) > STROKE_GOAL_S and painting(scene, item):
            waiting = True
            continue
        if key in REGISTRY.motion:
            if _playing():
                waiting = True  # sampled when the playback stops (it steps the scene's frames)
                continue
            REGISTRY.motion.discard(key)
            _guarded(_update_motion, scene, item)
        del REGISTRY.pending[key]
        stroke, started = key in REGISTRY.stroked, time.perf_counter()
        REGISTRY.stroked.discard(key)
        _guarded(update_field, scene, item)
        if stroke:
            REGISTRY.stroke_s[key] = time.perf_counter() - started
    return PAINT_MODE_POLL_S if waiting else None


def _playing() -> bool:
    wm = bpy.context.window_manager
    return any(w.screen is not None and w.screen.is_animation_playing for w in wm.windows)


def _update_motion(scene, item) -> None:
    """``update_track`` with the progress cursor (the window)."""
    wm = bpy.context.window_manager

    def progress(done, total):
        if done == 1:
            wm.progress_begin(0, total)
        wm.progress_update(done)

    try:
        update_track(scene, item, progress=progress)
    finally:
        wm.progress_end()


def stroke_seconds(scene, item) -> float:
    """How long the field's last stroke took to show (0 before any)."""
    return REGISTRY.stroke_s.get(key_of(scene, item), 0.0)


PAINT_MODES = {"WEIGHT_PAINT", "VERTEX_PAINT", "TEXTURE_PAINT", "SCULPT"}


def painting(scene, item) -> bool:
    """The field's terrain is being painted (weight, vertex, texture paint or sculpt mode)."""
    terrain = field_scene.terrain_object(scene, item)
    return terrain is not None and terrain.mode in PAINT_MODES


# --------------------------------------------------------------------------------------------
# Handlers


@persistent
def on_frame_change_pre(scene, depsgraph=None):
    """Simulate and write the new frame."""
    if REGISTRY.sampling:
        return  # tracks.sample steps the frames to read the colliders, not to show grass
    update_scene(scene)


@persistent
def on_frame_change_post(scene, depsgraph=None):
    """Before evaluation (``_pre``) an animated or just-moved camera still has its old matrix.
    After evaluation the camera is where it is at this frame: redo the LOD (eqs 7-11) and the
    writes if it moved; Blender then evaluates the edited meshes in a second pass."""
    if REGISTRY.sampling:
        return
    update_scene(scene, depsgraph, camera_moved_only=True)


@persistent
def on_render_pre(scene, *_args):
    """A render follows the scene camera, whatever the viewport showed: write every field of the
    rendered scene for it before Blender syncs the scene (a still has no frame change)."""
    REGISTRY.rendering = True
    update_scene(scene, camera_moved_only=True)


@persistent
def on_render_post(scene, *_args):
    """Back to the 3D views once the render is done (or cancelled): rewritten by a timer, out of
    the render's thread."""
    REGISTRY.rendering = False
    if not bpy.app.background:
        _refresh_later([key_of(s, item) for s, item in _live_fields()])


def watch_views() -> float | None:
    """Timer (the UI only): the 3D views moved (orbit, zoom, pan, another view) without a frame
    change or a data edit, so no handler runs: redo each field's LOD and window for them."""
    if not REGISTRY.fields or field_camera.rendering():
        return VIEW_POLL_S  # renders use the scene camera
    windows = bpy.context.window_manager.windows
    if any(w.screen is not None and w.screen.is_animation_playing for w in windows):
        return VIEW_POLL_S  # playback rewrites every frame anyway
    for scene in {w.scene for w in windows}:
        update_scene(scene, camera_moved_only=True)
    return VIEW_POLL_S


@persistent
def on_depsgraph_update_post(scene, depsgraph=None):
    """The camera was moved in the viewport (no frame change): follow it with the LOD. Only
    fields already written at this frame are touched, and only when the camera moved, so the
    mesh edits made here (which trigger another update) end the chain at once."""
    if not REGISTRY.fields or bpy.app.is_job_running("RENDER") or REGISTRY.sampling:
        return
    if depsgraph is not None and REGISTRY.paint_deps:
        _note_strokes(depsgraph)
    if depsgraph is not None and not bpy.app.background:
        _note_motion(scene, depsgraph)
    update_scene(scene, depsgraph, camera_moved_only=True)


def _note_strokes(depsgraph) -> None:
    """An edit of what a field's paint reads (a weight or vertex paint stroke on its terrain, an
    image, a keep-out object moved): count it, and apply it once the strokes settle (a timer)."""
    changed = set()
    for update in depsgraph.updates:
        original = getattr(update.id, "original", None) or update.id
        changed.add((original.id_type, original.name))
        if original.id_type == "OBJECT" and getattr(original, "data", None) is not None and update.is_updated_geometry:
            changed.add((original.data.id_type, original.data.name))
    touched = [key for key, deps in REGISTRY.paint_deps.items() if deps & changed]
    for key in touched:
        REGISTRY.strokes[key] = REGISTRY.strokes.get(key, 0) + 1
        REGISTRY.stroked.add(key)
        rt = REGISTRY.fields.get(key)
        if rt is not None:
            rt.dirty = True
    if touched and not bpy.app.background:
        _refresh_later(touched)


def _note_motion(scene, depsgraph) -> None:
    """An edit of a field's colliders or force fields (moved, keyed, a setting): look at its
    stored motion again once the edits settle (``update_track``)."""
    updated = {getattr(u.id, "original", u.id).name for u in depsgraph.updates if isinstance(u.id, bpy.types.Object)}
    actions = any(isinstance(u.id, bpy.types.Action) for u in depsgraph.updates)
    if not updated and not actions:
        return
    for item in getattr(scene, "windgrass", None).fields if hasattr(scene, "windgrass") else ():
        colls = [c for c in (getattr(item, "collider_collection", None), getattr(item, "effector_collection", None))
                 if c is not None]
        if colls and (actions or any(o.name in updated for c in colls for o in c.all_objects)):
            key = key_of(scene, item)
            REGISTRY.motion.add(key)
            _refresh_later([key])


def update_track(scene, item, progress=None) -> bool:
    """Sample the field's colliders and force fields again when what they were sampled from
    changed (``tracks.fingerprint``); returns True when it did. Steps the scene's frames: never
    from a frame or render handler."""
    params = properties.params_from_settings(item, scene)
    wanted = tracks.fingerprint(scene, item, params)
    have = tracks.stored_fingerprint(item)
    if not wanted:
        if have is not None:
            tracks.clear(item)
            rt = get_runtime(scene, item)
            if rt is not None:
                rt.dirty = True
            return True
        return False
    if have == wanted:
        return False
    terrain_of(scene, item, params)  # (the ground's height bounds the colliders' spheres)
    tracks.store(item, tracks.sample(scene, item, params, progress=progress), wanted)
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.dirty = True
    return True


@persistent
def on_load_post(*_args):
    """A new file: forget every runtime, and rebuild the objects of fields saved with another
    topology than their settings give now (files of earlier versions), here rather than in a
    frame handler."""
    REGISTRY.clear()
    REGISTRY.saved_bakes, REGISTRY.bake_root = bake.referenced_files(), str(bake.bake_root() or "") or None
    for scene, item in _fields():
        if bake.is_baked(item) and not bake.files_present(item):
            warn_once(f"field '{item.name}': {bake.status(scene, item, None)}")
    for scene, item in _live_fields():
        _guarded(apply_settings, scene, item)
        _guarded(update_field, scene, item)


@persistent
def on_load_pre(*_args):
    """Leaving a file: delete the bake files that the file on disk does not refer to (bakes
    undone or freed since it was saved, bakes never saved)."""
    _collect_bakes(REGISTRY.saved_bakes)


def _collect_bakes(keep) -> None:
    root = REGISTRY.bake_root
    try:
        gone = bake.collect_garbage(None if root is None else Path(root), set(keep))
    except OSError as exc:  # pragma: no cover (a read-only folder: the files stay)
        warn_once(f"bake files could not be cleaned up: {exc}")
        return
    if gone:
        print(f"Windgrass: deleted {len(gone)} bake file(s) no field refers to in {root}", flush=True)


def _at_exit() -> None:
    """Quitting Blender leaves the file: as on_load_pre, with plain files only."""
    _collect_bakes(REGISTRY.saved_bakes)


def plays_cache(item) -> bool:
    """Whether the field plays its bake (baked, and its files are on disk; else it plays live)."""
    return bake.is_baked(item) and bake.files_present(item)


def _fields():
    for scene in bpy.data.scenes:
        for item in getattr(scene, "windgrass", None).fields if hasattr(scene, "windgrass") else ():
            yield scene, item


def _live_fields():
    """(scene, item) of every field with objects that does not play a bake."""
    for scene, item in _fields():
        if item.collection is not None and not plays_cache(item):
            yield scene, item


@persistent
def on_save_pre(*_args):
    """A live field is saved as its settings, ground and materials: its slot meshes are emptied
    for the write (a 12.8 m field's slots are tens of MB) and filled again after it (on_save_post,
    and on load in a reopened file). A bake keeps its meshes: they carry the cache."""
    for scene, item in _live_fields():
        try:
            field_scene.clear_slots(item)
            _forget_slots(scene, item)
        except Exception as exc:  # pragma: no cover (a save must never fail because of the grass)
            warn_once(f"field '{item.name}': its slots are saved as they are ({type(exc).__name__}: {exc})")


@persistent
def on_save_post(*_args):
    """After a save: the slot meshes get their quads and the current frame back; bake files the
    saved file does not refer to are deleted (an undone bake, a freed one)."""
    for scene, item in _live_fields():
        _guarded(_refill, scene, item)
    REGISTRY.saved_bakes, REGISTRY.bake_root = bake.referenced_files(), str(bake.bake_root() or "") or None
    _collect_bakes(REGISTRY.saved_bakes)


def _refill(scene, item) -> None:
    field_scene.fill_slots(item, properties.params_from_settings(item, scene))
    update_field(scene, item)


@persistent
def on_undo_redo_post(*_args):
    """Undo and redo bring back the settings and datablocks of another step (which match: see
    the module docstring) with that step's mesh data: every runtime resolves again from the
    settings (its digest decides whether the engine is kept) and rewrites every slot. In the UI
    that waits for a timer, outside Blender's undo code; in scripts it happens at once. No
    datablock is added or removed here."""
    REGISTRY.errors.clear()
    for rt in REGISTRY.fields.values():
        rt.dirty = True
        rt.blades.state.forget()
        rt.cards.state.forget()
    fields = list(_live_fields())
    if bpy.app.background:
        for scene, item in fields:
            _guarded(update_field, scene, item)
    else:
        _refresh_later([key_of(scene, item) for scene, item in fields])


_HANDLERS = (
    (bpy.app.handlers.frame_change_pre, on_frame_change_pre),
    (bpy.app.handlers.frame_change_post, on_frame_change_post),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update_post),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.load_pre, on_load_pre),
    (bpy.app.handlers.render_pre, on_render_pre),
    (bpy.app.handlers.render_post, on_render_post),
    (bpy.app.handlers.render_cancel, on_render_post),
    (bpy.app.handlers.save_pre, on_save_pre),
    (bpy.app.handlers.save_post, on_save_post),
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
    atexit.register(_at_exit)
    if not bpy.app.background and not bpy.app.timers.is_registered(watch_views):
        bpy.app.timers.register(watch_views, first_interval=VIEW_POLL_S, persistent=True)


def unregister() -> None:
    for handlers, func in _HANDLERS:
        for existing in [h for h in handlers if _same(h, func)]:
            handlers.remove(existing)
    for timer in (_flush_pending, watch_views):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    properties.on_edit = None
    atexit.unregister(_at_exit)
    REGISTRY.clear()
