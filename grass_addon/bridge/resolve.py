"""A field resolved from its settings into what a frame needs (its ``registry.LiveField``), and
its frame written (``update_field``: the one call of an edit and of a frame handler, which
``guarded`` keeps from raising into Blender; the writes are ``frame_pass.write_frame``'s).

``resolve`` first reads every input (``read_inputs``): the field's parameters with the scene's
clock, its animated wind (F-curves sampled into keys, ``animation.py``), its terrain (sampled once
and kept while the terrain object and the grid hold), its paint, its stored collider and
force-field motion (``tracks.py``); then it keeps the field's engine while its digest holds
(telling it of new collider motion or paint) or makes the engine (``GrassField``) and its two
slot pools. Adds or removes no datablock (``lifecycle.apply_settings`` does); raises
WindgrassError on bad settings.
"""

from __future__ import annotations

import hashlib
import time
import traceback
from dataclasses import dataclass

import bpy

from .. import forces, interaction, look, roles, schema
from .. import paint as paint_core
from ..blocks import BlockCache, reshapes
from ..clock import Clock
from ..errors import WindgrassError
from ..field import GrassField
from ..schema import Params
from . import animation, bake, builds, maps, owned, paint_look, pools, properties, tracks
from . import camera as field_camera
from . import scene as field_scene
from .frame_pass import write_frame
from .registry import REGISTRY, Engine, LiveField, key_of, warn_once


def get_runtime(scene, item) -> LiveField | None:
    """The field's live record when its engine is resolved, else None."""
    return REGISTRY.built(key_of(scene, item))


def field_error(scene, item) -> str | None:
    """Why the field cannot be simulated now (a setting out of range, ...), or None."""
    state = REGISTRY.states.get(key_of(scene, item))
    return None if state is None else state.error


def _clock(scene) -> tuple[Clock, int]:
    return Clock.of_scene(scene), int(scene.frame_end)


def _wind_curves(scene, item, params: Params) -> tuple[dict, str]:
    """The field's animated wind F-curves ({} when none) and their fingerprint."""
    fcurves = animation.wind_fcurves(scene, item) if scene.animation_data is not None else {}
    if not fcurves:
        return {}, ""
    return fcurves, animation.fingerprint(fcurves, animation.sample_range(scene, params))


def _wind(scene, item, params: Params, previous: Engine | None):
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


def terrain_of(scene, item, params: Params, force: bool = False) -> tuple:
    """(heightfield, centre, key) of the field's terrain: sampled once and kept while the terrain
    object and the grid hold (the field's record); ``force`` (Rebuild) samples it again."""
    state = REGISTRY.live(key_of(scene, item))
    t_key = maps.terrain_key(scene, item, params)
    kept = state.terrain
    if not force and kept is not None and kept[0] == t_key:
        return kept[1], kept[2], t_key
    heightfield, centre = maps.sample_terrain(scene, item, params)
    state.sampled_terrain((t_key, heightfield, centre))
    return heightfield, centre, t_key


def paint_of(scene, item, params: Params):
    """The field's paint (``maps.paint_of``), read again only when its settings, its terrain or
    keep-out collection, or one of the datablocks it reads changed since (the record's ``strokes``,
    counted by ``handlers.on_depsgraph_update_post``)."""
    state = REGISTRY.live(key_of(scene, item))
    coll = item.keep_out_collection
    outline = [] if coll is None else sorted((o.name, [round(v, 6) for row in o.matrix_world for v in row])
                                             for o in coll.all_objects)
    signature = (tuple(paint_core.map_settings(params)), tuple(params.paint.extent), params.to_dict()["keep_out"],
                 maps.terrain_key(scene, item, params), "" if coll is None else coll.name, outline,
                 state.strokes, _ground_matrix(item))
    kept = state.paint
    if kept is not None and kept[0] == signature:
        return kept[1]
    paint = maps.paint_of(scene, item, params)
    state.sampled_paint(signature, paint, frozenset(maps.depends_on(scene, item, params)))
    return paint


def _ground_matrix(item) -> tuple:
    ground = owned.ground_object(item)
    return () if ground is None else tuple(round(v, 6) for row in ground.matrix_world for v in row)


def topology_of(params: Params, heightfield, item) -> str:
    """What the field's objects must be built for (``scene.topology``)."""
    return field_scene.topology(params, heightfield, paint_look.painted_settings(params, item))


@dataclass(frozen=True, eq=False)
class Inputs:
    """Everything a field's engine is made from, read from Blender in one place (``read_inputs``)
    before anything is decided."""

    params: schema.Params  # without the animated wind's values (the keys carry them)
    wind_keys: tuple | None
    wind_fingerprint: str
    heightfield: object  # terrain.Heightfield | None
    terrain_key: str
    topology: str
    colliders: list
    effectors: object  # forces effectors | None
    track: str  # tracks.fingerprint of the stored collider motion
    paint: object  # paint.Paint | None
    painted: str  # paint.fingerprint of it
    clock: tuple[Clock, int]
    frame: int  # the scene's current frame (a stroke's blocks are made again for it)
    digest: str  # what makes the frame: parameters, animated wind, topology, force fields, terrain
    ground: str  # what an engine kept through an edit in place needs the same: force fields, terrain


def read_inputs(scene, item, previous: Engine | None) -> Inputs:
    """The field's inputs now: its settings with the scene's clock, animated wind, terrain, paint
    and stored motion (``previous``: the engine whose sampled wind keys may be kept)."""
    params, wind_keys, fingerprint = _wind(scene, item, properties.params_from_settings(item, scene), previous)
    heightfield, _, t_key = terrain_of(scene, item, params)
    topology = topology_of(params, heightfield, item)  # (a keep-out collection is not a setting)
    colliders, effectors, track = tracks.stored(item)
    colliders = colliders + interaction.colliders_from_params(params)  # (a scene file's, in headless renders)
    effectors = forces.join(effectors, forces.effectors_from_params(params))
    ground = hashlib.sha1((tracks.effector_digest(item) + t_key
                           + (heightfield.fingerprint() if heightfield is not None else "")).encode()).hexdigest()
    digest = hashlib.sha1((params.digest() + fingerprint + topology + ground).encode()).hexdigest()
    paint = paint_of(scene, item, params)
    return Inputs(params, wind_keys, fingerprint, heightfield, t_key, topology, colliders, effectors, track, paint,
                  paint_core.fingerprint(paint), _clock(scene), scene.frame_current, digest, ground)


def resolve(scene, item, wait: bool = True, views=None) -> LiveField:
    """The field's record with its engine for its settings now: the engine kept when nothing it
    depends on changed (told of new collider motion or paint), retuned in place when the edit
    changes none of its blocks (``edit_parts``), else a new one: made at once, or with ``wait``
    False (the UI's edits) on a thread (``builds.Build``, seeked for ``views``), raising
    ``BuildPending`` until it is done. Reads Blender's data, never touches a datablock
    (``apply_settings`` does); raises WindgrassError on bad settings."""
    key = key_of(scene, item)
    live = REGISTRY.live(key)
    if live.engine is None:
        REGISTRY.forget_missing({key_of(s, f) for s in bpy.data.scenes for f in owned.scene_fields(s)})
        live = REGISTRY.live(key)
    inputs = read_inputs(scene, item, live.engine)
    _take_retuned(live, inputs, wait, item.name)
    engine = live.engine
    kept = engine is not None and engine.digest == inputs.digest
    retuned = not kept and engine is not None and engine.ground == inputs.ground and \
        engine.field.can_retune(inputs.params)
    if retuned and not wait and engine is not None and engine.field.reruns(inputs.params, inputs.wind_keys):
        _retune_later(live, engine, inputs, item.name, views)  # (a new run: on a thread, BuildPending)
    if kept or retuned:
        live.build_dropped()  # (a background build for other settings, no longer wanted: its result is let go)
        if retuned and engine is not None:
            _retune(live, engine, inputs)
        _update(live, live.resolved.field, inputs)
    else:
        _new_engine(live, inputs, item.name, wait, views)
    live.resolved_at(inputs.clock)
    for note in live.field.loop_notes():  # (here, not every frame: what breaks a loop changes only with this)
        warn_once(f"field '{item.name}' loops every {live.field.wind.loop:g} s, but {note}")
    return live


def _new_engine(live: LiveField, inputs: Inputs, name: str, wait: bool, views) -> None:
    """A new engine for ``inputs``: the background build's when it was made for them (waited for
    with ``wait``), else made now (``wait``) or started on a thread (``BuildPending``)."""
    job = live.building
    if job is not None and (wait or job.done.is_set()):
        if wait and job.digest == inputs.digest:
            job.wait()
        live.build_dropped()  # (taken now, or for other settings and waited for by no one)
        if job.done.is_set() and job.digest == inputs.digest:
            if job.failure is not None:
                raise job.failure
            _install(live, inputs, job.made, name, job.look_pools)
            return
        job = None
    if wait:
        _build(live, inputs, name)
        return
    if job is None:  # (one running: the next update after it starts one for the settings then)
        job = builds.Build(inputs.digest, inputs.frame, views, inputs=inputs)
        look.hold(job.looked)  # (the far grass's look, on its own thread, waits: the first look sooner)
        before = _grown(live, inputs)
        live.build_started(job.start(lambda report: _make(inputs, report, before), first_look=True))
    raise builds.BuildPending(name)


def _update(live: LiveField, field: GrassField, inputs: Inputs) -> None:
    """Tell the kept engine what changed that needs no new one: the colliders' motion (the wind's
    simulation stays: the digest holds the force fields) and the paint (only the blocks a stroke
    touched are made again)."""
    if live.track != inputs.track:
        field.update_colliders(inputs.colliders, inputs.effectors)
        live.colliders_told(inputs.track)
    if live.painted != inputs.painted:
        started = time.perf_counter()
        made = field.repaint(inputs.paint, frame=inputs.frame)
        live.repainted(inputs.painted, time.perf_counter() - started, made)


def _retune(live: LiveField, engine: Engine, inputs: Inputs) -> None:
    """The kept engine takes settings that change none of its blocks (``GrassField.retune``: a
    wind, solver, LOD or colour edit); its pools are kept while its objects' topology holds."""
    field = engine.field
    field.retune(inputs.params, wind_keys=inputs.wind_keys, colliders=inputs.colliders, effectors=inputs.effectors)
    _retuned(live, engine, field, inputs, live.painted)


def _retuned(live: LiveField, base: Engine, field: GrassField, inputs: Inputs, painted: str) -> None:
    """``field``, the engine ``base``'s field retuned to ``inputs`` (or its twin), becomes the
    record's engine; the pools of ``base`` are kept while the objects' topology holds."""
    same = base.topology == inputs.topology
    kept = base.pools if same else new_pools(field)
    live.engine_made(Engine(field, inputs.params, inputs.digest, inputs.ground, inputs.wind_fingerprint,
                            inputs.wind_keys, inputs.terrain_key, inputs.topology, kept),
                     painted, inputs.track, kept=True)


def _retune_later(live: LiveField, engine: Engine, inputs: Inputs, name: str, views) -> None:
    """Start the run of a wind or solver edit in the UI on a thread: the engine's ``twin`` retuned
    and seeked for ``views`` (``builds.Build``), while the engine goes on showing its frames; one
    at a time (a build running is waited for). Raises ``BuildPending``."""
    if live.building is None:
        job = builds.Build(inputs.digest, inputs.frame, views, inputs=inputs, base=engine, painted=live.painted)
        twin = engine.field.twin(progress=job.report)  # (here: the blocks as they are now)

        def make(_report) -> GrassField:
            twin.retune(inputs.params, wind_keys=inputs.wind_keys, colliders=inputs.colliders,
                        effectors=inputs.effectors)
            return twin

        live.build_started(job.start(make, first_look=engine.topology == inputs.topology))  # (its objects fit)
    raise builds.BuildPending(name)


def _take_retuned(live: LiveField, inputs: Inputs, wait: bool, name: str) -> None:
    """A retune run on a thread (``_retune_later``) that is done becomes the engine, even when the
    settings moved on while it ran (a slider dragged on: the grass follows one run behind), while
    its objects' topology is the settings' now and its base is still the engine; ``wait`` (a frame
    or a render) waits for one made for the settings now."""
    job = live.building
    if job is None or job.base is None:
        return
    if wait and job.digest == inputs.digest:
        job.wait()
    if not job.done.is_set():
        return
    live.build_dropped()
    if job.failure is not None:
        if job.digest == inputs.digest:
            raise job.failure
        return
    made_for, base = job.inputs, live.engine
    if base is not None and base is job.base and made_for.topology == inputs.topology \
            and made_for.ground == inputs.ground:
        job.made.report_progress(_seek_progress(name))
        _retuned(live, base, job.made, made_for, job.painted)


def new_pools(field: GrassField) -> dict[str, pools.SlotPool]:
    """New slot pools, one a role, for the engine ``field``'s shapes."""
    return {role: pools.SlotPool(role, shape) for role, shape in field.shapes.items()}


def _make(inputs: Inputs, progress, before: BlockCache | None = None) -> GrassField:
    """The engine of ``inputs`` (numpy only: a background build runs it on its thread); ``before``:
    ``_grown``'s blocks."""
    return GrassField(inputs.params, wind_keys=inputs.wind_keys, terrain=inputs.heightfield, paint=inputs.paint,
                      colliders=inputs.colliders, effectors=inputs.effectors, progress=progress, before=before)


def _grown(live: LiveField, inputs: Inputs) -> BlockCache | None:
    """The engine's blocks as they are now (``fork``) when ``inputs`` change only its blades' rest
    shapes (a stiffness edit, ``blocks.reshapes``) on the same terrain and paint: the new engine
    makes its blocks from the blades they grew instead of growing them again."""
    engine = live.engine
    if (engine is None or engine.terrain_key != inputs.terrain_key or live.painted != inputs.painted
            or not reshapes(engine.params, inputs.params)):
        return None
    return engine.field.cache.fork()


def _build(live: LiveField, inputs: Inputs, name: str) -> None:
    """A new engine and its slot pools for ``inputs``: its objects show nothing of it yet."""
    _install(live, inputs, _make(inputs, _seek_progress(name), _grown(live, inputs)), name)


def _install(live: LiveField, inputs: Inputs, field: GrassField, name: str, look_pools: dict | None = None) -> None:
    """``field`` becomes the record's engine, with new slot pools, or those its first look was
    written through (``look_pools``, ``builds.Build``) when they are of its shapes: they know
    which blocks each slot shows, so its first frame writes positions, not colours again."""
    field.report_progress(_seek_progress(name))
    kept = look_pools if look_pools is not None and set(look_pools) == set(field.shapes) and all(
        look_pools[role].shape == shape for role, shape in field.shapes.items()) else new_pools(field)
    live.engine_made(Engine(field, inputs.params, inputs.digest, inputs.ground, inputs.wind_fingerprint,
                            inputs.wind_keys, inputs.terrain_key, inputs.topology, kept),
                     inputs.painted, inputs.track)


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


def current(scene, item, wait: bool = True, views=None) -> LiveField:
    """The record a frame handler writes from: as it is unless its settings may have changed
    (an edit, undo), the scene's clock or the animated wind changed under it (then resolved
    again, numpy only), or it has no engine yet (``wait``, ``views``: see ``resolve``)."""
    live = REGISTRY.live(key_of(scene, item))
    if live.engine is None or live.stale or live.building is not None:
        return resolve(scene, item, wait, views)
    engine = live.engine
    if live.clock != _clock(scene) or _wind_curves(scene, item, engine.params)[1] != engine.wind_fingerprint:
        return resolve(scene, item, wait, views)
    if engine.terrain_key and maps.terrain_key(scene, item, engine.params) != engine.terrain_key:
        warn_once(f"the terrain of field '{item.name}' is gone or changed; the grass keeps the ground it "
                  "was built on until Rebuild (on flat ground without a terrain)")
    return live


# ---------------------------------------------------------------------------- a field brought to its
# settings and written for the scene's frame (the frame handlers' and the edits' one call)


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
