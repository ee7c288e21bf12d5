"""A field's datablocks brought to its settings: build, rebuild, bake, remove.

Blender's undo stores the whole file after each operator and each property edit and, on Ctrl+Z,
reuses the datablocks it believes unchanged since the last step: a datablock added or deleted
between steps (by a timer, a handler) leaves it pointers to freed memory, and Blender crashes. So
datablocks change only here, inside the operator or the property edit that asked for it
(``edits.mark_dirty`` applies them at once), and on file load; never from a timer, a frame
handler or an undo handler. Every undo step then holds objects that match its settings.
"""

from __future__ import annotations

import bpy

from .. import memory
from .. import paint as paint_core
from ..errors import WindgrassError
from ..schema import Params
from . import bake, maps, owned, properties, wind_force
from . import scene as field_scene
from .registry import REGISTRY, key_of
from .resolve import guarded, resolve, terrain_of, topology_of, update_field


def apply_settings(scene, item, force: bool = False, look_later: bool = False) -> None:
    """Bring the field's datablocks to its settings now: the objects are rebuilt when their
    topology changed (always with ``force``: Rebuild, which also re-samples the terrain and frees
    a bake), the materials' values refreshed. A baked field is left as baked (an edit makes its
    bake stale, see bake.status); a field without objects (never built, deleted by hand) gets
    none. ``look_later`` (an edit in the UI): a look that takes time to work out is written when it
    is ready (``edits.show_look``). Raises WindgrassError on bad settings (nothing is changed then)."""
    if bake.is_baked(item):
        if not force:
            return
        bake.free_bake(scene, item)
    if item.collection is None and not force:
        return
    params = properties.params_from_settings(item, scene)
    maps.hold_images(item, params)  # (image maps kept with the file, and through renames)
    memory.check(params, bpy.path.abspath)  # before anything is built: a card range or a map too large
    # an opened file: its slots were never saved (scene.leave_out_of_files), they are built now
    missing = item.collection is not None and field_scene.slots_missing(item, params)
    if (force or missing) and item.terrain is not None:
        try:  # the terrain's matrix and modifiers as they are now (a file just opened: not yet evaluated)
            bpy.context.view_layer.update()
        except (RuntimeError, AttributeError):  # no depsgraph here (mid-render, a restricted context)
            pass
    heightfield, centre, _ = terrain_of(scene, item, params, force=force or missing)
    field_scene.separate_copy(item)
    coll = item.collection
    if force or missing or coll is None or coll.get(owned.TOPOLOGY) != topology_of(params, heightfield, item):
        shown = field_scene.build_slots(scene, item, params, heightfield, centre, look_later)
        REGISTRY.live(key_of(scene, item)).look_waits(not shown)
        forget_slots(scene, item, rebuilt=True)
    else:
        if field_scene.fill_slots(item, params):  # a file of an earlier version: its slots saved empty
            forget_slots(scene, item)
        field_scene.leave_out_of_files(field_scene.slot_blocks(item))  # (and so are copies of them)
        refill_ground(scene, item, params)  # and its painted ground grid emptied
        if field_scene.refresh_heads(item, params):  # a head shape, leaves or an Own Plant edited
            forget_slots(scene, item)
        write_look(scene, item, params, heightfield, look_later)
    # The frame handler edits meshes while a render runs: keep the interface locked then.
    if not scene.render.use_lock_interface:
        scene.render.use_lock_interface = True


def write_look(scene, item, params: Params, heightfield, later: bool = False) -> None:
    """Write the field's materials and its ground's canopy heights (``scene.refit_ground``) for
    ``params``; ``later`` (an edit in the UI): once their look is worked out on a thread
    (``look.ask``; the record says it waits, ``edits.show_look`` writes it then)."""
    shown = field_scene.update_field_materials(item, params, scene, later=later)
    live = REGISTRY.live(key_of(scene, item))
    live.look_waits(not shown)
    if shown and field_scene.refit_ground(item, params, heightfield):
        live.paint_look_lost()


def refill_ground(scene, item, params: Params) -> None:
    """Make the painted ground grid a save emptied again (``scene.fill_ground``); the paint's look
    on it is then written at the next update."""
    if field_scene.fill_ground(item, params):
        REGISTRY.live(key_of(scene, item)).paint_look_lost()


def forget_slots(scene, item, rebuilt: bool = False) -> None:
    """The field's slot meshes hold something else now (``rebuilt``: new objects for new
    settings): its pools write every slot next time."""
    live = REGISTRY.live(key_of(scene, item))
    if rebuilt:
        live.edited()
    live.slots_changed()


def build_field(scene, item, force: bool = False, wait: bool = True) -> bpy.types.Collection:
    """Add, Rebuild (``force``), scripts: the field's datablocks for its settings and its current
    frame written at once (``apply_settings``, ``update_field``; ``wait`` False, Add in the UI:
    the far grass's look and the engine made on threads, ``builds.Build``, its objects hidden
    until its first look is written: ``edits.build_in_background``). A setting out of range raises
    before anything is built; once the datablocks are built nothing raises: a frame that cannot
    be simulated (a paint map that needs a terrain, ...) is recorded for the panel
    (``field_error``) and its grass hidden, so the operator finishes and Blender's undo step holds
    the datablocks it made (a cancelled operator that changed datablocks leaves undo pointing at
    freed ones: Ctrl+Z crashed)."""
    if bake.is_baked(item) and not force:
        return item.collection
    apply_settings(scene, item, force=True if item.collection is None else force, look_later=not wait)
    if force:
        reset_field(scene, item)
    guarded(update_field, scene, item, wait=wait)
    write_read_me()
    return item.collection


def start_bake(scene, item, first: int, last: int, groups: int = 1, fmt: str = "alembic") -> bake.Baker:
    """A bake of frames ``first``-``last`` of the field in ``groups`` steps, ready to step
    (``bake.Baker``); BakeError or ParameterError on what prevents it."""
    properties.params_from_settings(item, scene)  # a setting out of range stops here, named
    if bake.is_baked(item):
        free_bake(scene, item)
    rt = resolve(scene, item)
    if item.collection is None or item.collection.get(owned.TOPOLOGY) != rt.topology:
        build_field(scene, item)
    digest = params_digest(scene, item)
    assert digest is not None  # (the settings were read above)
    return bake.Baker(scene, item, first, last, digest, groups, fmt)


def bake_field(scene, item, first: int, last: int, fmt: str = "alembic"):
    """Bake frames ``first``-``last`` of the field into Alembic (or USD: ``fmt``) caches beside
    the .blend and play the field from them (``bake.py``); returns the cache folder."""
    folder = start_bake(scene, item, first, last, fmt=fmt).finish()
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
    state = REGISTRY.states.get(key_of(scene, item))
    kept = None if state is None else state.paint
    painted = paint_core.fingerprint(kept[1]) if kept is not None else ""
    return f"{digest}|{painted}" if painted else digest

READ_ME = "Windgrass - read me"


def write_read_me() -> None:
    """A text block that says, in a Blender without Windgrass, what the grass needs."""
    live: list[str] = []
    baked: list[str] = []
    for s in bpy.data.scenes:
        for item in owned.scene_fields(s):
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


def share_map(scene, item) -> bpy.types.Object:
    """The field's map (``wind_force.py``: the wind and ``FIELD_ATTRIBUTES`` on a grid on its
    ground, for an artist's node trees and Blender's hair and cloth), made on any Blender and
    written for this frame; each frame writes it from then on. Returns the map's object."""
    if item.collection is None:
        build_field(scene, item)
    wind_force.ensure(item)
    rt = update_field(scene, item)
    if rt is not None and rt.field is not None:
        wind_force.write(item, rt.field, scene.frame_current)
    return wind_force.map_object(item)


def blow_physics(scene, item, obj=None) -> tuple[str, int]:
    """The field's wind for Blender's hair and cloth (``wind_force.py``): its map (``share_map``)
    in the file's Windgrass Wind collection, which becomes the Effectors Collection of ``obj``'s
    Hair or Cloth Dynamics. Returns (the collection's name, how many dynamics blow)."""
    if not wind_force.available():
        raise WindgrassError(wind_force.needs_note())
    share_map(scene, item)
    winds = bpy.data.collections[wind_force.COLLECTION]
    return winds.name, (wind_force.link_into(obj, winds) if obj is not None else 0)


def remove_field(scene, item) -> None:
    """Delete everything the field made (``scene.remove_datablocks``, its bake) and forget its
    runtime."""
    reset_field(scene, item)
    bake.free_bake(scene, item)
    field_scene.remove_datablocks(item)
    _remove_terrain_copy(item)


TERRAIN_COPY_KEY = "wg_terrain_copy"  # the field item's: the linked terrain Duplicate Field made for it


def _remove_terrain_copy(item) -> None:
    """The linked copy of a terrain Duplicate Field made for the field (issue #63: Remove left it
    behind), when it is still the field's terrain and no other field grows on it; its mesh stays
    with the original."""
    copy = item.get(TERRAIN_COPY_KEY)
    if not isinstance(copy, bpy.types.Object) or item.terrain != copy:
        return
    others = [f for s in bpy.data.scenes for f in owned.scene_fields(s) if f != item and f.terrain == copy]
    if not others:
        bpy.data.objects.remove(copy, do_unlink=True)


def reset_field(scene, item) -> None:
    """Forget the runtime of ``item``: the next update resolves it from its settings again."""
    state = REGISTRY.states.get(key_of(scene, item))
    if state is not None:
        state.drop()
