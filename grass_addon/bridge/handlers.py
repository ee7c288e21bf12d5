"""Blender's handlers and timers for the grass fields (all ``@persistent``, added once by ``register``).

  ``frame_change_pre``       simulate and write the new frame;
  ``frame_change_post``      redo the LOD if the camera moved during evaluation (animated camera);
  ``depsgraph_update_post``  the same when the camera is moved without a frame change; count
                             paint strokes and collider edits;
  ``load_post``              empty the registry, bring outdated objects up to date;
  ``save_pre``/``save_post``  a painted ground grid is saved empty (made again after);
  ``undo_post``/``redo_post`` the settings may be others now: resolve again, rewrite every slot;
  ``render_pre``/``_post``   a render follows the scene camera, the viewport the 3D views after.
Which position shows which block is a function of the frame and camera alone (canonical order),
so frames rendered apart equal frames rendered in one run.
"""

from __future__ import annotations

import atexit
from pathlib import Path

import bpy
from bpy.app.handlers import persistent

from . import bake, floor, owned, properties
from . import camera as field_camera
from . import scene as field_scene
from .edits import flush_pending, mark_dirty, painting, poll_builds, refresh_later, show_look
from .lifecycle import apply_settings, refill_ground
from .registry import REGISTRY, key_of, warn_once
from .resolve import guarded, update_field, update_scene

VIEW_POLL_S = 0.1  # how often the viewport's views are looked at (orbiting changes no data, so no handler runs)


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
    for item in owned.scene_fields(scene):  # (an edit's look still worked out on a thread: now, for the render)
        if REGISTRY.live(key_of(scene, item)).look_waiting:
            guarded(show_look, scene, item, later=False)
    update_scene(scene, camera_moved_only=True)


@persistent
def on_render_post(scene, *_args):
    """Back to the 3D views once the render is done (or cancelled): rewritten by a timer, out of
    the render's thread."""
    REGISTRY.rendering = False
    if not bpy.app.background:
        refresh_later([key_of(s, item) for s, item in _live_fields()])


def watch_views() -> float | None:
    """Timer (the UI only): the 3D views moved (orbit, zoom, pan, another view) without a frame
    change or a data edit, so no handler runs: redo each field's LOD and window for them. Views
    that start or stop drawing grass with EEVEE turn the floor grid off or back on (``floor.py``)."""
    floor.follow_views()
    if not REGISTRY.fields or field_camera.rendering():
        return VIEW_POLL_S  # renders use the scene camera
    windows = bpy.context.window_manager.windows
    for scene in {w.scene for w in windows}:
        show_while_painting(scene)
    if any(w.screen is not None and w.screen.is_animation_playing for w in windows):
        return VIEW_POLL_S  # playback rewrites every frame anyway
    for scene in {w.scene for w in windows}:
        update_scene(scene, camera_moved_only=True)
    return VIEW_POLL_S


def show_while_painting(scene) -> None:
    """A field whose terrain is in Weight, Vertex or Texture Paint (or Sculpt) mode is hidden in
    the viewport, so the artist sees what they paint, and shown again when they leave the mode
    (renders never hide it: this is the viewport's eye only)."""
    for item in owned.scene_fields(scene):
        if item.collection is None:
            continue
        state = REGISTRY.live(key_of(scene, item))
        hide = painting(scene, item)
        if hide == state.hidden_for_paint:
            continue
        for obj in owned.field_objects(item):
            if scene.view_layers and obj.name in bpy.context.view_layer.objects:
                obj.hide_set(hide)
        state.shown_while_painting(hide)


@persistent
def on_depsgraph_update_post(scene, depsgraph=None):
    """The camera was moved in the viewport (no frame change): follow it with the LOD. Only
    fields already written at this frame are touched, and only when the camera moved, so the
    mesh edits made here (which trigger another update) end the chain at once."""
    if REGISTRY.unchanged and depsgraph is not None and _edited(depsgraph):
        REGISTRY.unchanged = False
    if not REGISTRY.fields or bpy.app.is_job_running("RENDER") or REGISTRY.sampling:
        return
    if depsgraph is not None and any(s.paint_deps for s in REGISTRY.states.values()):
        _note_strokes(depsgraph)
    if depsgraph is not None and not bpy.app.background:
        _note_motion(scene, depsgraph)
    update_scene(scene, depsgraph, camera_moved_only=True)


def _edited(depsgraph) -> bool:
    """An update of a datablock other than the grass's own and the scene holding it: the artist
    edited the file (``REGISTRY.unchanged``). When the grass's own shading changed (its ground's
    material taking a paint image), Blender updates every object's shading with it: an object
    whose only update is its shading is then no edit."""
    updates = [(u, getattr(u.id, "original", None) or u.id) for u in depsgraph.updates]
    own = {id(o) for _, o in updates if getattr(o, "get", lambda key: None)("wg_uid") is not None}
    own_shading = any(u.is_updated_shading for u, o in updates if id(o) in own)
    for update, original in updates:
        if isinstance(original, bpy.types.Scene) or original.is_embedded_data or id(original) in own:
            continue  # (a material's node tree: its material is among the updates too)
        if own_shading and isinstance(original, bpy.types.Object) and update.is_updated_shading \
                and not (update.is_updated_geometry or update.is_updated_transform):
            continue
        return True
    return False


def _note_strokes(depsgraph) -> None:
    """An edit of what a field's paint reads (a weight or vertex paint stroke on its terrain, an
    image, a keep-out object moved): count it, and apply it once the strokes settle (a timer)."""
    changed = set()
    for update in depsgraph.updates:
        original = getattr(update.id, "original", None) or update.id
        changed.add((original.id_type, original.name))
        if original.id_type == "OBJECT" and getattr(original, "data", None) is not None and update.is_updated_geometry:
            changed.add((original.data.id_type, original.data.name))
    touched = [key for key, state in REGISTRY.states.items() if state.paint_deps & changed]
    for key in touched:
        REGISTRY.states[key].stroke()
    if touched and not bpy.app.background:
        refresh_later(touched)


def _note_motion(scene, depsgraph) -> None:
    """An edit of a field's colliders or force fields (moved, keyed, a setting): look at its
    stored motion again once the edits settle (``update_track``)."""
    updated = {getattr(u.id, "original", u.id).name for u in depsgraph.updates if isinstance(u.id, bpy.types.Object)}
    # (an object deleted from a collection, or moved out of it, updates the collection)
    collections = {getattr(u.id, "original", u.id).name for u in depsgraph.updates
                   if isinstance(u.id, bpy.types.Collection)}
    actions = any(isinstance(u.id, bpy.types.Action) for u in depsgraph.updates)
    if not updated and not actions and not collections:
        return
    for item in owned.scene_fields(scene):
        colls = [c for c in (item.collider_collection, item.effector_collection) if c is not None]
        if colls and (actions or any(c.name in collections for c in colls)
                      or any(o.name in updated for c in colls for o in c.all_objects)):
            key = key_of(scene, item)
            REGISTRY.live(key).motion_edited()
            refresh_later([key])


@persistent
def on_load_post(*_args):
    """A new file: forget every runtime, and rebuild the objects of fields saved with another
    topology than their settings give now (files of earlier versions), here rather than in a
    frame handler."""
    REGISTRY.clear()
    REGISTRY.saved_bakes, REGISTRY.bake_root = bake.referenced_files(), str(bake.bake_root() or "") or None
    for scene, item in _fields():
        newer = properties.upgrade(item)  # (a file of an earlier version: its settings brought to this one's)
        if newer:
            warn_once(newer)
        if bake.is_baked(item) and not bake.files_present(item):
            warn_once(f"field '{item.name}': {bake.status(scene, item, None)}")
    for scene, item in _live_fields():
        guarded(apply_settings, scene, item)
        guarded(update_field, scene, item)
    REGISTRY.unchanged = True


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


def _fields():
    for scene in bpy.data.scenes:
        for item in owned.scene_fields(scene):
            yield scene, item


def _live_fields():
    """(scene, item) of every field with objects that does not play a bake."""
    for scene, item in _fields():
        if item.collection is not None and not bake.plays_cache(item):
            yield scene, item


@persistent
def on_save_pre(*_args):
    """A live field is saved as its settings, ground and materials: its slot objects are runtime
    data that no file holds (``scene.leave_out_of_files``: saves, autosaves and quit.blend alike).
    A painted field's ground grid on flat ground is emptied for the write and made again after it
    (on_save_post, and on load). The 3D views' floor grids are saved as the artist set them."""
    floor.give_back(keep=True)
    REGISTRY.emptied = []
    for scene, item in _live_fields():
        try:
            if field_scene.clear_ground(scene, item, properties.params_from_settings(item, scene)):
                REGISTRY.emptied.append(key_of(scene, item))
        except Exception as exc:  # pragma: no cover (a save must never fail because of the grass)
            warn_once(f"field '{item.name}': its ground is saved as it is ({type(exc).__name__}: {exc})")


@persistent
def on_save_post(*_args):
    """After a save: emptied ground grids get their cells back; bake files the saved file does not
    refer to are deleted (an undone bake, a freed one)."""
    floor.take_again()
    for scene, item in _live_fields():
        if key_of(scene, item) in REGISTRY.emptied:
            guarded(_refill, scene, item)
    REGISTRY.emptied = []
    REGISTRY.saved_bakes, REGISTRY.bake_root = bake.referenced_files(), str(bake.bake_root() or "") or None
    _collect_bakes(REGISTRY.saved_bakes)
    REGISTRY.unchanged = True  # (the refill above is the grass, not an edit)


def _refill(scene, item) -> None:
    refill_ground(scene, item, properties.params_from_settings(item, scene))
    update_field(scene, item)


@persistent
def on_undo_redo_post(*_args):
    """Undo and redo bring back the settings and datablocks of another step (which match: see
    the module docstring) with that step's mesh data: every runtime resolves again from the
    settings (its digest decides whether the engine is kept) and rewrites every slot. In the UI
    that waits for a timer, outside Blender's undo code; in scripts it happens at once. No
    datablock is added or removed here. A field's error stays until that refresh finds it again or
    not (cleared here, a hidden field's panel said nothing for up to 20 s in a loaded window)."""
    for live in REGISTRY.fields.values():
        live.edited()
        live.slots_changed()
    fields = list(_live_fields())
    if bpy.app.background:
        for scene, item in fields:
            guarded(update_field, scene, item)
    else:
        refresh_later([key_of(scene, item) for scene, item in fields])


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
    for timer in (flush_pending, poll_builds, watch_views):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    properties.on_edit = None
    atexit.unregister(_at_exit)
    floor.give_back(keep=False)
    REGISTRY.clear()
