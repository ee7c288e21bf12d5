"""A grass field in Blender, frame by frame: the add-on's public face of the bridge.

Operators, panels, scripts and tests call these; each lives in the one module of its job:

* ``resolve.py``: a field's settings resolved into its live record (parameters with the scene's
  clock, the numpy engine ``GrassField``, its two slot pools), then its frame written
  (``update_field``: an edit's and a frame handler's one call; ``guarded``: never raising);
* ``lifecycle.py``: the field's datablocks brought to its settings (build, rebuild, bake,
  remove), only inside operators, property edits and file load (Blender's undo needs it);
* ``frame_pass.py``: one frame: views -> ``GrassField.frame`` -> writes;
* ``edits.py``: property edits, strokes and collider edits applied once they settle;
* ``handlers.py``: Blender's handlers and timers, ``register`` and ``unregister``;
* ``registry.py``: the one module-level state, one live record per field (``LiveField``).

It is also the UI's one door: ``operators/`` and ``panels/`` import from here alone (the structure
test holds them to it), so what they may touch is the list under "The UI's vocabulary" below: the
settings (``properties``), the stored motion, maps, bakes and farm bundles the panels show and the
operators start, and the engine's schema, presets and errors that the settings are made from.
"""

from __future__ import annotations

# The UI's vocabulary: what operators and panels use, besides the functions below.
from .. import presets, schema
from ..clock import Clock
from ..errors import WindgrassError
from ..grid import FieldGrid
from ..simulation import seek_note
from . import animation, bake, farm_job, maps, owned, properties, tracks, wind_force
from .bake import plays_cache
from .edits import (
    EDIT_SETTLE_S,
    PAINT_MODE_POLL_S,
    STROKE_GOAL_S,
    build_in_background,
    flush_pending,
    mark_dirty,
    poll_builds,
    refresh_later,
    store_track,
    stroke_seconds,
    update_track,
)
from .handlers import register, unregister
from .lifecycle import (
    TERRAIN_COPY_KEY,
    apply_settings,
    bake_field,
    bake_status,
    blow_physics,
    build_field,
    free_bake,
    params_digest,
    remove_field,
    reset_field,
    share_map,
    start_bake,
    write_read_me,
)
from .registry import REGISTRY, LiveField, key_of
from .resolve import field_error, get_runtime, resolve, terrain_of, topology_of, update_field, update_scene


def loop_notes(scene, item) -> list[str]:
    """What keeps the field's frames from repeating with its loop (``loop.notes``; [] when none)."""
    state = REGISTRY.built(key_of(scene, item))
    return [] if state is None else state.field.loop_notes()


def building_percent(scene, item) -> int | None:
    """How far the field's new engine is built in the background (0-100), None when none is."""
    state = REGISTRY.states.get(key_of(scene, item))
    return None if state is None else state.building_percent()


def background_work(scene, item) -> str | None:
    """What of the field is being worked out on a thread after an edit, in a sentence for the
    panel (a new field, a new run of the wind or the solver, and whether its first look is drawn
    meanwhile; the far grass's look), None when nothing is."""
    state = REGISTRY.states.get(key_of(scene, item))
    if state is None:
        return None
    percent = state.building_percent()
    if percent is not None:
        what = "Simulating the new settings" if state.building.base is not None \
            else "Building the field for its new settings"
        shown = ", a first look shown" if state.building.shows_first_look else ""
        return f"{what}: {percent} %{shown}"
    return "Working out the far grass's look for the new settings" if state.look_waiting else None


def blades_drawn(scene, item) -> int | None:
    """How many blades the field's objects draw now (the viewport's share, a render's all), None
    before a frame is written."""
    state = REGISTRY.states.get(key_of(scene, item))
    return None if state is None else state.blades_drawn


def shown_when_done(scene, item) -> None:
    """Wait for the field's work on threads (a new run, a new field, its look: ``builds``,
    ``look``) and write it (the timer's work, for scripts that made an edit as the UI does)."""
    import time

    state = REGISTRY.states.get(key_of(scene, item))
    while state is not None and (state.building is not None or state.look_waiting):
        if state.building is not None:
            state.building.wait()
        time.sleep(0.01)
        poll_builds()


def scene_clock(scene) -> Clock:
    """The scene's clock (frame rate with its ``fps_base``, first frame), as every field reads it."""
    return Clock.of_scene(scene)


__all__ = ["animation", "bake", "farm_job", "FieldGrid", "maps", "owned", "presets", "properties", "schema",
           "seek_note", "tracks", "WindgrassError", "apply_settings", "bake_field", "bake_status", "build_field",
           "build_in_background",
           "background_work", "blades_drawn", "building_percent", "loop_notes", "EDIT_SETTLE_S", "field_error",
           "LiveField", "flush_pending", "free_bake", "get_runtime", "key_of", "mark_dirty", "PAINT_MODE_POLL_S",
           "params_digest", "plays_cache", "poll_builds", "refresh_later", "register", "REGISTRY", "remove_field",
           "reset_field", "resolve", "scene_clock", "shown_when_done", "start_bake", "store_track", "STROKE_GOAL_S",
           "stroke_seconds", "TERRAIN_COPY_KEY", "terrain_of", "topology_of", "unregister", "update_field",
           "update_scene", "update_track", "write_read_me", "blow_physics", "share_map", "wind_force"]
