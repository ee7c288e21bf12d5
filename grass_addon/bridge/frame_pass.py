"""One frame of a field written into Blender: views -> ``GrassField.frame`` -> writes.

The engine computes the whole frame (``GrassField.frame``: window, state, LOD, each role's blocks
and vertices, velocities, gust offset, trail map); this module asks for it with the views the
frame is seen from (``camera.field_views``) and writes it: the slot pools (``pools.py``), the gust
mapping and the trail image of the materials. ``resolve.update_field`` calls it once the field's
engine is brought to its settings. No ``bpy.ops``, no datablock added or removed, no per-blade
Python loop.
"""

from __future__ import annotations

import bpy
import numpy as np

from . import camera as field_camera
from . import materials, owned, textures, wind_force
from .registry import LiveField, warn_once


def write_frame(scene, item, rt: LiveField, depsgraph=None, views=None) -> None:
    """The frame as the engine computes it (``GrassField.frame``: wind, solver, cell data, LOD
    from the views, each role's blocks and vertices, gust offset, trail map), written: the views
    are ``camera.field_views`` (the scene camera in renders, the 3D views in the viewport).

    With the scene's motion blur on, or at a sub-frame (Blender evaluates frame + subframe for
    each motion-blur step), the vertices are those of that instant and carry their velocity."""
    if views is None:
        views = field_camera.field_views(scene, item, depsgraph)
    shown = _write_roles(scene, item, rt.pools, rt.field, views, blur=bool(scene.render.use_motion_blur))
    if not views and rt.field.notice:
        warn_once(f"field '{item.name}' has no camera to follow: {rt.field.notice}")
    _write_lod_scale(item, rt, rt.field, shown)
    _write_trails(item, rt, shown.trail)
    if shown.subframe == 0.0:  # (Blender's hair and cloth step whole frames)
        wind_force.write(item, rt.field, shown.frame)
    rt.written(shown.frame, shown.subframe, field_camera.signature(views), shown.blades_drawn())
    job = rt.building
    if job is not None and job.shows_first_look:  # (the grass before the edit, written over its first look)
        job.first_look_shown(written=False)


def write_first_look(scene, item, rt: LiveField, pools: dict, field, views) -> None:
    """A build's first look (``GrassField.first_look``, worked out on its thread) written into the
    field's objects through ``pools`` while its first frame is worked out: the roles' slots, the
    gust offset and the far canopy's reach (a new field's look draws its detail nearer:
    ``GrassField.most_blocks``). The record keeps the frame it wrote: the next frame change, or the
    build when done, writes over it."""
    _write_lod_scale(item, rt, field, _write_roles(scene, item, pools, field, views))


def _write_lod_scale(item, rt: LiveField, field, shown) -> None:
    """The far canopy's LOD distances times the frame's scale (the screen's, a first look's reach),
    written when it is another than the canopy shows (``rt.lod_scale``)."""
    scale = float(getattr(shown.lod, "scale", 1.0))  # (no LOD: 1)
    if scale != 1.0 or rt.lod_scale != 1.0:
        materials.set_lod_scale(field.params, owned.recorded(item, owned.ROLE_CANOPY_MATERIAL), scale)
        rt.lod_scaled(scale)


def _write_roles(scene, item, pools: dict, field, views, blur: bool = False):
    """``field``'s frame at the scene's instant seen from ``views`` (the viewport's share of the
    blades, a render's all), its roles written through ``pools`` and its gust offset into the
    materials; returns the frame (``frame.Frame``)."""
    amount = 1.0 if field_camera.rendering() else float(field.params.lod.viewport_amount)  # (renders: all)
    shown = field.frame(scene.frame_current, float(scene.frame_subframe), views, blur=blur, amount=amount)
    for part in shown.roles():
        pools[part.role].write(item, part)
    if shown.gust is not None:  # the far grass's gust waves travel with the mean wind
        materials.set_gust_offset(*shown.gust, field.params, owned.recorded(item, owned.ROLE_CARD_MATERIAL),
                                  owned.recorded(item, owned.ROLE_CANOPY_MATERIAL))
    return shown


def _write_trails(item, rt: LiveField, trail) -> None:
    """The far canopy's trampled trails (``interaction.trail_map``, or None): its image and
    mapping, written when they changed."""
    if rt.trail_written and trail is None and rt.trail is None:
        return
    image = owned.recorded(item, owned.ROLE_TRAIL_IMAGE)
    if trail is not None and isinstance(image, bpy.types.Image):
        if rt.trail is None or rt.trail.extent != trail.extent or not np.array_equal(rt.trail.flat, trail.flat):
            textures.write_trail_image(image, trail.flat)
    materials.set_trail(owned.recorded(item, owned.ROLE_CANOPY_MATERIAL), trail)
    rt.trail_shown(trail)
