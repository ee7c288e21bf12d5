"""One frame of a field written into Blender: views -> ``GrassField.frame`` -> writes.

The engine computes the whole frame (``GrassField.frame``: window, state, LOD, each role's blocks
and vertices, velocities, gust offset, trail map); this module asks for it with the views the
frame is seen from (``camera.field_views``) and writes it: the slot pools (``pools.py``), the gust
mapping and the trail image of the materials. A field that cannot be simulated records why and
hides its grass (``guarded``), so no frame shows the grass of another frame. No ``bpy.ops``, no
datablock added or removed, no per-blade Python loop.
"""

from __future__ import annotations

import traceback

import bpy
import numpy as np

from .. import roles
from ..errors import WindgrassError
from . import bake, builds, materials, owned, paint_look, pools, textures, wind_force
from . import camera as field_camera
from .registry import REGISTRY, LiveField, key_of, warn_once
from .resolve import current, get_runtime


def write_frame(scene, item, rt: LiveField, depsgraph=None, views=None) -> None:
    """The frame as the engine computes it (``GrassField.frame``: wind, solver, cell data, LOD
    from the views, each role's blocks and vertices, gust offset, trail map), written: the views
    are ``camera.field_views`` (the scene camera in renders, the 3D views in the viewport).

    With the scene's motion blur on, or at a sub-frame (Blender evaluates frame + subframe for
    each motion-blur step), the vertices are those of that instant and carry their velocity."""
    if views is None:
        views = field_camera.field_views(scene, item, depsgraph)
    amount = 1.0 if field_camera.rendering() else float(rt.params.lod.viewport_amount)  # (renders: all)
    shown = rt.field.frame(scene.frame_current, float(scene.frame_subframe), views,
                           blur=bool(scene.render.use_motion_blur), amount=amount)
    if not views and rt.field.notice:
        warn_once(f"field '{item.name}' has no camera to follow: {rt.field.notice}")
    for part in shown.roles():
        rt.pools[part.role].write(item, part)
    scale = float(getattr(shown.lod, "scale", 1.0))  # the screen's scale of the LOD distances (no LOD: 1)
    if scale != 1.0 or rt.lod_scale != 1.0:
        materials.set_lod_scale(rt.params, owned.registered(item).get(owned.ROLE_CANOPY_MATERIAL), scale)
        rt.lod_scaled(scale)
    if shown.gust is not None:  # the far grass's gust waves travel with the mean wind
        reg = owned.registered(item)
        materials.set_gust_offset(*shown.gust, rt.params, reg.get(owned.ROLE_CARD_MATERIAL),
                                  reg.get(owned.ROLE_CANOPY_MATERIAL))
    _write_trails(item, rt, shown.trail)
    if shown.subframe == 0.0:  # (Blender's hair and cloth step whole frames)
        wind_force.write(item, rt.field, shown.frame)
    rt.written(shown.frame, shown.subframe, field_camera.signature(views), shown.blades_drawn())


def _write_trails(item, rt: LiveField, trail) -> None:
    """The far canopy's trampled trails (``interaction.trail_map``, or None): its image and
    mapping, written when they changed."""
    if rt.trail_written and trail is None and rt.trail is None:
        return
    reg = owned.registered(item)
    image = reg.get(owned.ROLE_TRAIL_IMAGE)
    if trail is not None and isinstance(image, bpy.types.Image):
        if rt.trail is None or rt.trail.extent != trail.extent or not np.array_equal(rt.trail.flat, trail.flat):
            textures.write_trail_image(image, trail.flat)
    materials.set_trail(reg.get(owned.ROLE_CANOPY_MATERIAL), trail)
    rt.trail_shown(trail)


def update_field(scene, item, depsgraph=None, camera_moved_only: bool = False, wait: bool = True) -> LiveField | None:
    """Write the field ``item`` of ``scene`` for ``scene.frame_current`` (a frame handler's work).
    Returns its live record, or None when the field has no objects (not built, or deleted by hand).

    ``camera_moved_only``: skip the write when this frame was written with the same camera
    (the ``frame_change_post`` pass, see ``on_frame_change_post``). ``wait`` False (the UI's
    edits): a new engine is built on a thread (``builds.BuildPending`` until it is done)."""
    if item.collection is None:
        if owned.was_built(item):  # (a field being added has none yet)
            warn_once(f"field '{item.name}' has no collection (deleted?); nothing to update")
        return None
    if bake.plays_cache(item):
        return None  # its objects play the cache
    views = None
    if camera_moved_only:
        rt = get_runtime(scene, item)
        if rt is None or rt.frame != scene.frame_current or rt.subframe != float(scene.frame_subframe):
            return rt  # not written at this instant yet: the frame handlers will do it
        views = field_camera.field_views(scene, item, depsgraph)
        if rt.camera_signature == field_camera.signature(views):
            return rt  # same views, same frame: nothing to do (cheap: no parameter read)
    if not wait:
        views = field_camera.field_views(scene, item, depsgraph)
    try:
        rt = current(scene, item, wait, views)
    except builds.BuildPending:
        rt = REGISTRY.live(key_of(scene, item))
        if rt.engine is None or item.collection.get(owned.TOPOLOGY) != rt.engine.topology:
            raise  # (nothing of it fits the objects as they are: they are collapsed until it is built)
        # The engine of the settings before stays shown while the new one is made (a stiffness or
        # a seed edit: its objects still fit): a slider dragged keeps its grass in view, and the
        # grass catches up with it when the build is done.
    if item.collection.get(owned.TOPOLOGY) != rt.topology:
        # Windgrass rebuilds the objects whenever the settings ask for it (apply_settings); only a
        # change made around it (objects edited by hand, settings written as raw ID properties)
        # gets here, and a frame handler must not add or delete datablocks.
        raise WindgrassError(f"the objects of field '{item.name}' were not built for its settings "
                             "(changed outside Windgrass); press Rebuild")
    if rt.paint_shown != rt.painted:
        paint_look.update_paint_look(item, rt.params, rt.field.cache.paint)
        rt.paint_look_shown()
    write_frame(scene, item, rt, depsgraph, views)
    return rt


def update_scene(scene, depsgraph=None, camera_moved_only: bool = False) -> None:
    """Write every field of ``scene`` for its current frame; never raises into Blender."""
    for item in owned.scene_fields(scene):
        guarded(update_field, scene, item, depsgraph, camera_moved_only=camera_moved_only)


def guarded(work, scene, item, *args, camera_moved_only: bool = False, **kw) -> None:
    """``work(scene, item, ...)``, never raising: a field that cannot be simulated (a setting
    out of range, a failure) records the error for the panel and for scripts (``field_error``)
    and hides its grass, so no frame shows the grass of another frame; a field whose new engine
    is being built in the background (``builds.BuildPending``) hides its grass until it is ready."""
    key = key_of(scene, item)
    try:
        if camera_moved_only:
            kw["camera_moved_only"] = True
        work(scene, item, *args, **kw)
    except builds.BuildPending:  # (its objects may be built for the new settings already: collapsed as they are)
        for role in roles.NAMES:
            pools.collapse_objects(owned.slot_objects(item, role).values())
        REGISTRY.live(key).slots_changed()
        REGISTRY.live(key).no_error()  # (its settings were read: the engine is being made for them)
    except Exception as exc:  # a handler must not break playback or rendering
        message = str(exc) if isinstance(exc, WindgrassError) else f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, WindgrassError):  # a fault of Windgrass, not a setting: its trace for a report
            traceback.print_exc()
        live = REGISTRY.live(key)
        warn_once(f"field '{item.name}' cannot be simulated, its grass is hidden: {message}")
        try:
            hide(scene, item)
        except Exception as hide_exc:  # pragma: no cover (objects gone mid-render)
            warn_once(f"field '{item.name}' could not be hidden: {hide_exc}")
        live.drop(error=message)  # resolved again (and checked again) at the next update
    else:
        # Only a frame written clears the error: another work done (the datablocks brought to the
        # settings, the motion sampled) says nothing of whether the grass can be simulated (issue
        # #63: after an undo a field that cannot read its paint map lost its error for seconds).
        if work is update_field and not camera_moved_only and key in REGISTRY.states:
            REGISTRY.states[key].no_error()


def hide(scene, item) -> None:
    """Collapse every slot of the field to a point (nothing drawn) and forget what they showed."""
    rt = get_runtime(scene, item)
    if rt is not None:
        for pool in rt.pools.values():
            pool.collapse(item)
        rt.unwritten()
        return
    for role in roles.NAMES:
        pools.collapse_objects(owned.slot_objects(item, role).values())
