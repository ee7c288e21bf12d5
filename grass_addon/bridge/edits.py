"""Edits of a field's settings, paint and colliders, applied as Blender users expect.

A property edit or an operator brings the field's datablocks to its settings at once
(``lifecycle.apply_settings``: the undo step Blender pushes after it holds objects that match);
the engine's update follows at once in scripts and background renders, and in the UI once the
edits settle (a timer), so dragging a slider stays fluid. Paint strokes and moved colliders are
counted by the handlers and applied the same way; a field whose strokes take long waits while
its terrain is in a paint mode.
"""

from __future__ import annotations

import threading
import time

import bpy

from .. import look
from ..errors import WindgrassError
from . import bake, maps, owned, properties, tracks
from .frame_pass import write_first_look
from .lifecycle import apply_settings, build_field, write_look
from .registry import REGISTRY, key_of
from .resolve import guarded, new_pools, terrain_of, update_field

# Edits in the UI arrive once per slider step; they are coalesced and applied once the user pauses
# for this long, so dragging a slider on a large field does not re-simulate at every step; while the
# drag goes on, the grass follows it every FOLLOW_S (one update waits at a time, never a queue).
EDIT_SETTLE_S = 0.15
FOLLOW_S = 0.3
BUILD_POLL_S = 0.1  # how often a field being built in the background is looked at
FIRST_LOOK_POLL_S = 0.02  # ... while an edit's first look is being worked out (it shows at once)
STROKE_GOAL_S = 0.5  # a field whose strokes take longer to show follows when paint mode is left
PAINT_MODE_POLL_S = 0.25


def mark_dirty(scene, item, defer: bool | None = None) -> None:
    """Settings of ``item`` changed (a property edit, an operator): its datablocks follow at once
    (``apply_settings``: the undo step Blender pushes after the edit holds objects that match),
    then the engine is resolved again and the frame written (the digest decides what is rebuilt).
    Scripts and background renders (``bpy.app.background``) get the engine's update at once; in
    the UI (``defer``) it waits until the edits settle (a timer), so dragging a slider stays fluid.
    """
    REGISTRY.unchanged = False  # (a setting edited: the file is not as saved)
    if item.collection is None or bake.is_baked(item):
        return
    live = REGISTRY.live(key_of(scene, item))
    live.edited()
    deferred = defer if defer is not None else not bpy.app.background
    guarded(apply_settings, scene, item, look_later=deferred)  # (in the UI a slow look is worked out on a thread)
    if item.collider_collection is not None or item.effector_collection is not None \
            or tracks.TRACK_KEY in item.collection:
        live.motion_edited()
    if not deferred:
        if live.moved:
            live.motion_looked_at()
            guarded(update_track, scene, item)
        guarded(update_field, scene, item)
        return
    refresh_later([key_of(scene, item)])


def refresh_later(keys) -> None:
    """Write these fields' current frame once the edits settle (a timer: numpy and vertex writes
    only, no datablock is added or removed there)."""
    now = time.monotonic()
    for key in keys:
        REGISTRY.live(key).edit_waits(now)
    if not bpy.app.timers.is_registered(flush_pending):
        bpy.app.timers.register(flush_pending, first_interval=EDIT_SETTLE_S)


def flush_pending() -> float | None:
    """Timer: write the fields whose edits settled; run again shortly while the user is still
    dragging. A field whose strokes take longer than STROKE_GOAL_S to show (a large field) waits
    while its terrain is in a paint mode: it follows when the artist leaves it."""
    pending = {key: s for key, s in REGISTRY.states.items() if s.pending is not None}
    latest = max((s.pending for s in pending.values() if s.pending is not None), default=0.0)
    first = min((s.waiting_since for s in pending.values() if s.waiting_since is not None), default=latest)
    wait = min(latest + EDIT_SETTLE_S, first + FOLLOW_S) - time.monotonic()  # settled, or a drag followed
    if wait > 0:
        return wait
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    waiting = False
    for key, state in pending.items():
        scene, item = _field_of(scenes, key)
        if item is None or item.collection is None:
            state.edit_shown()
            continue
        if state.stroke_s > STROKE_GOAL_S and painting(scene, item):
            waiting = True
            continue
        if state.moved:
            if _playing():
                waiting = True  # sampled when the playback stops (it steps the scene's frames)
                continue
            state.motion_looked_at()
            if _quick_to_sample(scene, item):  # (a long sampling waits for Update Motion: no freeze)
                guarded(_update_motion, scene, item)
        state.edit_shown()
        stroke, started = state.stroked, time.perf_counter()
        guarded(update_field, scene, item, wait=stroke)  # (a new engine on a thread; a stroke shows at once)
        state.stroke_shown(time.perf_counter() - started if stroke else None)
    watch_builds()
    return PAINT_MODE_POLL_S if waiting else None


def build_in_background(scene, item) -> bpy.types.Collection:
    """Add Grass Field in the UI: the field's datablocks at once, its engine made on a thread
    (``lifecycle.build_field`` with ``wait`` False: the window is not held while the blocks are
    made and the warm-up simulated), its first look and then its frame written by the timer."""
    before = threading.Event()  # (the field's objects ask for its look before its build begins: held)
    look.hold(before)
    try:
        collection = build_field(scene, item, wait=False)
    finally:
        before.set()
    watch_builds()
    return collection


def watch_builds() -> None:
    """Poll the fields' background work (``poll_builds``) until it is done."""
    if any(s.building is not None or s.look_waiting for s in REGISTRY.states.values()) \
            and not bpy.app.timers.is_registered(poll_builds):
        bpy.app.timers.register(poll_builds, first_interval=_poll_interval())


def poll_builds() -> float | None:
    """Timer: write the fields whose background build (``builds.Build``) is done (or its first
    look, once worked out), and the materials whose look was worked out on a thread
    (``show_look``); run again while one is not."""
    running = False
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    for key, state in list(REGISTRY.states.items()):
        if state.building is not None and state.building.first_look is not None:
            _show_first_look(scenes, key, state, state.building)
        if state.look_waiting and look.working():
            running = True  # (asking whether it is ready reads every setting: once the thread is done)
        elif state.look_waiting:
            scene, item = _field_of(scenes, key)
            if item is None or item.collection is None:
                state.look_waits(False)
            else:
                guarded(show_look, scene, item)
                running = running or state.look_waiting
                if not state.look_waiting:
                    _redraw()
        job = state.building
        if job is None:
            continue
        if not job.done.is_set():
            running = True
            continue
        scene, item = _field_of(scenes, key)
        if item is None:
            state.build_dropped()
            continue
        guarded(update_field, scene, item, wait=False)
        running = running or state.building is not None
        _redraw()
    return _poll_interval() if running else None


def _poll_interval() -> float:
    waiting = any(s.building is not None and s.building.looks_first for s in REGISTRY.states.values())
    return FIRST_LOOK_POLL_S if waiting else BUILD_POLL_S


def _show_first_look(scenes: dict, key, state, job) -> None:
    """Write the first look of the engine ``job`` makes (``builds.Build.first_look``) while the
    frame it was worked out for is shown, its first frame is not done and the field's objects fit
    it; then let it go."""
    scene, item = _field_of(scenes, key)
    pools = _first_look_pools(scene, item, state, job)
    written: list = []  # (a write that failed hands its pools on to nothing)
    if pools is not None:
        guarded(_written_first_look, scene, item, state, pools, job, written)
        if job.base is None:
            state.slots_changed()  # (the engine before, still shown at other frames, writes every slot again)
        _redraw()
    job.first_look_shown(written=pools is not None, pools=pools if written and job.base is None else None)


def _written_first_look(scene, item, state, pools: dict, job, written: list) -> None:
    write_first_look(scene, item, state, pools, job.first_look, job.views)
    written.append(True)


def _first_look_pools(scene, item, state, job) -> dict | None:
    """The pools a first look is written through: a run's, the engine's it retunes; a new field's,
    new ones. None when it is not to be written (see ``_show_first_look``)."""
    if item is None or item.collection is None or job.done.is_set() or scene.frame_current != job.at_frame \
            or item.collection.get(owned.TOPOLOGY) != job.inputs.topology:
        return None
    if job.base is None:
        return new_pools(job.first_look)
    return state.pools if state.engine is job.base and job.base.topology == job.inputs.topology else None


def show_look(scene, item, later: bool = True) -> None:
    """Write the field's materials for its settings once their look is worked out (``later``:
    asked for on a thread, ``look.ask``; else at once: a render is about to start)."""
    params = properties.params_from_settings(item, scene)
    write_look(scene, item, params, terrain_of(scene, item, params)[0], later)


def _field_of(scenes: dict, key) -> tuple:
    """(scene, field item) of the record ``key`` (``scenes``: by session uid); Nones when gone."""
    scene = scenes.get(key[0])
    return scene, properties.field_by_uid(scene, key[1]) if scene else None


def _redraw() -> None:
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type in ("VIEW_3D", "PROPERTIES"):
                area.tag_redraw()


def _quick_to_sample(scene, item) -> bool:
    try:
        params = properties.params_from_settings(item, scene)
    except WindgrassError:
        return True  # (the update reports the setting)
    return tracks.sampling_seconds(scene, item, params) <= tracks.AUTO_SAMPLE_S


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
    state = REGISTRY.states.get(key_of(scene, item))
    return 0.0 if state is None else state.stroke_s

PAINT_MODES = {"WEIGHT_PAINT", "VERTEX_PAINT", "TEXTURE_PAINT", "SCULPT"}


def painting(scene, item) -> bool:
    """The field's terrain is being painted (weight, vertex, texture paint or sculpt mode)."""
    terrain = maps.terrain_object(scene, item)
    return terrain is not None and terrain.mode in PAINT_MODES


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
            REGISTRY.live(key_of(scene, item)).edited()
            return True
        return False
    if have == wanted:
        return False
    terrain_of(scene, item, params)  # (the ground's height bounds the colliders' spheres)
    store_track(scene, item, tracks.sample(scene, item, params, progress=progress), wanted)
    return True


def store_track(scene, item, track, wanted: str) -> None:
    """Keep the sampled motion ``track`` (of fingerprint ``wanted``) with the file; the field
    takes it at its next update."""
    tracks.store(item, track, wanted)
    REGISTRY.live(key_of(scene, item)).edited()
