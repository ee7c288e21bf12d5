"""Per-frame driver: the one runtime registry and the frame handlers.

``RUNTIMES`` maps ``(scene session uid, field uid)`` to a ``FieldRuntime`` holding the numpy engine
(``GrassField``) built from the field's parameters, the digest it was built from and reusable
float32 buffers. Nothing in Blender's file refers to it: it is dropped on file load and rebuilt
from the stored parameters (the state at frame N is a function of params, seed and N).

Each frame ``update_scene`` seeks every field of the scene to ``scene.frame_current``, computes
the LOD weights of eqs 7-11 from the scene camera, gives the nearest visible blocks that need
blades (K_g > 0, eq 8) to the blade slots and those that need cards (K_b > 0, eqs 7/11) to the
card slots, and writes vertex positions and the per-vertex attributes with ``foreach_set``.
A slot object holds k blocks ("positions" ``wg_slot * k .. wg_slot * k + k - 1``,
``scene.blocks_per_slot``): one position write per object per frame.
No ``bpy.ops``, no per-blade Python loops; the only Python loop runs over slot objects.

Handlers (all ``@persistent``, added once by ``register``):
  ``frame_change_pre``       simulate and write the new frame (``update_scene``);
  ``frame_change_post``      redo the LOD if the camera moved during evaluation (animated camera);
  ``depsgraph_update_post``  the same when the camera is moved without a frame change;
  ``load_post``              drop every runtime; ``undo_post``/``redo_post`` forget slot state.
Which position shows which block is a function of the frame and camera alone (canonical order), so
frames rendered apart equal frames rendered in one run.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from dataclasses import field as dc_field

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ..errors import WindgrassError
from . import materials
from . import scene as field_scene

# Position state: which block a slot position shows. UNKNOWN forces a full write (new runtime, reopened file).
FREE = -1
UNKNOWN = -2

# Animated wind F-curves become one key per frame (the solver reads the wind once per frame,
# paper IV) from the simulation start to frame_end; past frame_end the range grows in steps of
# this many frames, so the sampled keys (and the cache key) rarely change.
_EXTEND_FRAMES = 240

RUNTIMES: dict[tuple[int, str], FieldRuntime] = {}
# The last error of each field whose settings cannot be simulated (shown by the panel; its grass
# is hidden rather than left at a stale frame), by the same key as RUNTIMES.
ERRORS: dict[tuple[int, str], str] = {}
_WARNED: set[str] = set()


def _warn_once(text: str) -> None:
    """Report a problem in the console once; a frame handler must never raise into Blender."""
    if text not in _WARNED:
        _WARNED.add(text)
        print(f"Windgrass: {text}")


@dataclass
class FieldRuntime:
    field: object  # GrassField
    params: object  # Params the field was built from
    digest: str
    wind_fingerprint: str = ""
    wind_keys: tuple | None = None
    # Block shown at every slot position (FREE / UNKNOWN); object wg_slot s holds positions s*k..s*k+k-1.
    blade_position_block: np.ndarray = dc_field(default_factory=lambda: np.zeros(0, np.int32))
    card_position_block: np.ndarray = dc_field(default_factory=lambda: np.zeros(0, np.int32))
    blade_buffer: np.ndarray | None = None
    card_buffer: np.ndarray | None = None
    # Last written frame, for tests and panels: blocks shown by slots, the LOD weights.
    frame: int | None = None
    blade_blocks: np.ndarray = dc_field(default_factory=lambda: np.zeros(0, np.int32))
    card_blocks: np.ndarray = dc_field(default_factory=lambda: np.zeros(0, np.int32))
    lod: object = None
    camera_signature: tuple | None = None
    # Terrain: the heightfield sampled from item.terrain at build time (None: flat), the
    # world XY the field is centred on, and what the samples depend on besides the mesh data.
    params_digest: str = ""
    terrain_key: str = ""
    heightfield: object = None
    terrain_centre: tuple | None = None


def runtime_key(scene, item) -> tuple[int, str]:
    """The scene's session uid (kept through renames and undo, new for a copied scene) and the
    field's uid."""
    return scene.session_uid, str(item.uid)


def field_error(scene, item) -> str | None:
    """Why the field cannot be simulated now (a setting out of range, ...), or None."""
    return ERRORS.get(runtime_key(scene, item))


def _forget_stale_runtimes() -> None:
    """Drop runtimes of scenes or fields that no longer exist (deleted scene, removed field)."""
    alive = {(s.session_uid, str(f.uid)) for s in bpy.data.scenes if hasattr(s, "windgrass")
             for f in s.windgrass.fields}
    for key in [k for k in RUNTIMES if k not in alive]:
        del RUNTIMES[key]
    for key in [k for k in ERRORS if k not in alive]:
        del ERRORS[key]


def get_runtime(scene, item) -> FieldRuntime | None:
    return RUNTIMES.get(runtime_key(scene, item))


# --------------------------------------------------------------------------------------------
# Parameters and animated wind


def _action_fcurves(anim_data):
    """F-curves of the animation data's action; Blender 4.4+ layered actions use channelbags
    (``action.fcurves`` is gone in 5.0)."""
    action = anim_data.action if anim_data is not None else None
    if action is None:
        return ()
    slot = getattr(anim_data, "action_slot", None)
    try:
        from bpy_extras import anim_utils
        get_bag = getattr(anim_utils, "action_get_channelbag_for_slot", None)
    except ImportError:  # pragma: no cover
        get_bag = None
    if get_bag is not None and slot is not None:
        bag = get_bag(action, slot)
        return tuple(bag.fcurves) if bag is not None else ()
    return tuple(getattr(action, "fcurves", ()))


def wind_fcurves(scene, item) -> dict[str, object]:
    """{'speed': fcurve, 'direction': fcurve} of this field's animated wind, if any."""
    base = item.path_from_id("wind")
    wanted = {f"{base}.speed": "speed", f"{base}.direction": "direction"}
    out = {}
    for fc in _action_fcurves(scene.animation_data):
        role = wanted.get(fc.data_path)
        if role is not None and not fc.mute:
            out[role] = fc
    return out


def _fcurve_fingerprint(fc) -> bytes:
    n = len(fc.keyframe_points)
    data = np.empty(n * 6, dtype=np.float32)
    if n:
        fc.keyframe_points.foreach_get("co", data[: 2 * n])
        fc.keyframe_points.foreach_get("handle_left", data[2 * n: 4 * n])
        fc.keyframe_points.foreach_get("handle_right", data[4 * n:])
    extra = f"{fc.extrapolation}|{len(fc.modifiers)}|" + ",".join(k.interpolation for k in fc.keyframe_points)
    return data.tobytes() + extra.encode()


def sample_range(scene, params) -> tuple[int, int]:
    """Frames from the simulation start (t = -preroll) to frame_end, extended in steps when the
    current frame lies beyond it, so the range (and the cache key) rarely changes."""
    r = params.render
    first = r.frame_start - int(math.ceil(params.simulation.preroll * r.fps))
    last = r.frame_end
    if scene.frame_current > last:
        last += int(math.ceil((scene.frame_current - last) / _EXTEND_FRAMES)) * _EXTEND_FRAMES
    return first, last


def sample_wind_keys(fcurves: dict, params, frames: tuple[int, int]) -> tuple:
    """(time_s, speed_m_s, direction_deg) per frame from the F-curves (one sample a frame).

    Time follows the engine's clock t = (frame - frame_start) / fps; direction F-curves hold
    radians (Blender's angle unit) and become degrees (the schema's unit).
    """
    r = params.render
    frame_list = range(frames[0], frames[1] + 1)
    speed_fc, dir_fc = fcurves.get("speed"), fcurves.get("direction")
    speeds = [max(0.0, speed_fc.evaluate(f)) if speed_fc else params.wind.speed for f in frame_list]
    dirs = [math.degrees(dir_fc.evaluate(f)) if dir_fc else params.wind.direction for f in frame_list]
    return tuple(((f - r.frame_start) / r.fps, float(s), float(d)) for f, s, d in zip(frame_list, speeds, dirs))


def field_params(scene, item, previous: FieldRuntime | None = None):
    """(params, wind_keys, wind_fingerprint, digest) of the field now."""
    from . import properties

    params = properties.params_from_settings(item, scene)
    fcurves = wind_fcurves(scene, item) if scene.animation_data is not None else {}
    if not fcurves:
        return params, None, "", params.digest()
    # The animated values change every frame; the keys carry them, so the digest must not.
    from .. import schema

    stable = {f"wind.{role}": schema.BY_NAME[f"wind.{role}"].default for role in fcurves}
    stable_params = params.replace(stable)
    frames = sample_range(scene, params)
    h = hashlib.sha1(repr(frames).encode())
    for role in sorted(fcurves):
        h.update(role.encode())
        h.update(_fcurve_fingerprint(fcurves[role]))
    fingerprint = h.hexdigest()
    if previous is not None and previous.wind_fingerprint == fingerprint and previous.wind_keys is not None:
        keys = previous.wind_keys
    else:
        keys = sample_wind_keys(fcurves, params, frames)
    digest = hashlib.sha1((stable_params.digest() + fingerprint).encode()).hexdigest()
    return stable_params, keys, fingerprint, digest


def ensure_runtime(scene, item) -> FieldRuntime:
    """The field's runtime, rebuilt when its parameters (or animated wind) or its terrain changed.

    The terrain is sampled once per build (never per frame): the samples are kept while the
    terrain object and the grid stay the same; Rebuild (``scene.build_field``) drops the runtime,
    so an edited terrain mesh is sampled again. The digest includes the heights' fingerprint."""
    from ..field import GrassField

    key = runtime_key(scene, item)
    rt = RUNTIMES.get(key)
    if rt is None:
        _forget_stale_runtimes()
    params, keys, fingerprint, digest = field_params(scene, item, rt)
    t_key = field_scene.terrain_key(scene, item, params)
    if rt is not None and rt.params_digest == digest and rt.terrain_key == t_key:
        return rt
    if rt is not None and rt.terrain_key == t_key:
        heightfield, centre = rt.heightfield, rt.terrain_centre
    else:
        heightfield, centre = field_scene.sample_terrain(scene, item, params)
    full_digest = digest if heightfield is None else hashlib.sha1(
        (digest + heightfield.fingerprint()).encode()).hexdigest()
    rt = FieldRuntime(field=GrassField(params, wind_keys=keys, terrain=heightfield), params=params,
                      digest=full_digest, wind_fingerprint=fingerprint, wind_keys=keys, params_digest=digest,
                      terrain_key=t_key, heightfield=heightfield, terrain_centre=centre)
    RUNTIMES[key] = rt
    if item.collection is not None:
        field_scene.update_field_materials(item, params)
    return rt


# --------------------------------------------------------------------------------------------
# Camera


def blender_camera(scene, to_field=None, depsgraph=None):
    """``lod.Camera`` of the scene camera in the field's frame, or None without a camera.

    With ``depsgraph`` the evaluated camera is used (its animation at this frame)."""
    from ..lod import Camera

    cam = scene.camera
    if cam is None or cam.type != "CAMERA":
        return None
    if depsgraph is not None:
        cam = cam.evaluated_get(depsgraph)
    matrix = cam.matrix_world
    if to_field is not None:
        matrix = to_field @ matrix
    rot = np.array(matrix.to_3x3(), dtype=np.float64)
    position = np.array(matrix.translation, dtype=np.float64)
    forward = -rot[:, 2]  # a Blender camera looks down its local -Z
    up = rot[:, 1]
    forward /= max(np.linalg.norm(forward), 1e-12)
    up /= max(np.linalg.norm(up), 1e-12)
    r = scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-9)
    data = cam.data
    if data.type == "ORTHO":
        # No perspective: take the angle that shows the ortho width from the camera's distance
        # to the field centre (LOD distances still come from the camera position).
        dist = max(float(np.linalg.norm(position)), 1e-3)
        fov_x = 2.0 * math.atan(0.5 * data.ortho_scale / dist)
    else:
        fit = data.sensor_fit
        if fit == "AUTO":
            # The sensor width spans the larger image side.
            fov_x = data.angle_x if aspect >= 1.0 else 2.0 * math.atan(math.tan(0.5 * data.angle_x) * aspect)
        elif fit == "HORIZONTAL":
            fov_x = data.angle_x
        else:
            fov_x = 2.0 * math.atan(math.tan(0.5 * data.angle_y) * aspect)
    fov_x = min(max(fov_x, 1e-3), math.radians(179.0))
    return Camera(position=position.astype(np.float32), forward=forward.astype(np.float32),
                  up=up.astype(np.float32), fov_x=float(fov_x), aspect=float(aspect))


# --------------------------------------------------------------------------------------------
# Slot assignment and writes


def assign_slots(n_slots: int, chosen: np.ndarray) -> np.ndarray:
    """Block shown at every slot position: the chosen blocks in block order, then FREE.

    Canonical on purpose: what each slot object holds is a function of the frame (and camera)
    alone, not of the frames visited before, so a render farm rendering frames 3-4 alone gets
    the same objects, hence the same pixels, as a run over frames 1-4 (the state at frame N is
    a function of the parameters, the seed and N). Colours are rewritten only for objects where a position's
    block changed. The shown blocks fill positions 0 .. len(chosen) - 1, FREE the rest."""
    out = np.full(n_slots, FREE, dtype=np.int32)
    blocks = np.sort(np.asarray(chosen, dtype=np.int32))[:n_slots]
    out[: len(blocks)] = blocks
    return out


def nearest_blocks(candidates: np.ndarray, distance: np.ndarray, count: int) -> np.ndarray:
    """Up to ``count`` candidate blocks, nearest first (stable for equal distances)."""
    idx = np.flatnonzero(candidates)
    order = np.argsort(distance[idx], kind="stable")
    return idx[order[:count]].astype(np.int32)


def _choose_positions(state: np.ndarray, n_positions: int, needs: np.ndarray,
                      block_distance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(current, previous, chosen) block of every pool position: the nearest blocks that ``need``
    this LOD, in block order in the first positions (``assign_slots``), the rest FREE. ``previous``
    is UNKNOWN everywhere when the pool was resized (forces a full write)."""
    previous = state if len(state) == n_positions else np.full(n_positions, UNKNOWN, dtype=np.int32)
    chosen = nearest_blocks(needs, block_distance, n_positions)
    return assign_slots(n_positions, chosen), previous, chosen


def _write_position(mesh, verts: np.ndarray) -> None:
    """Write float32 positions in bulk and tell Blender they changed.

    The bulk write goes to the ``position`` attribute (about 10x faster than
    ``vertices.foreach_set("co")``), but that path does not tag the positions as changed, so
    Blender would keep the bounds of an earlier frame and a render would depend on the frames
    rendered before it. Assigning one vertex through ``MeshVertex.co`` runs Blender's
    positions-changed update (bounds and normals recomputed) for the whole mesh.
    """
    mesh.attributes["position"].data.foreach_set("vector", verts.ravel())
    if len(mesh.vertices):
        first = mesh.vertices[0]
        first.co = first.co


def _slot_writes(current: np.ndarray, previous: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(write, changed) per slot object: write unless all its k positions are FREE now and were
    FREE before (it stays collapsed); changed where some position shows another block."""
    cur, prev = current.reshape(-1, k), previous.reshape(-1, k)
    write = ~((cur == FREE).all(axis=1) & (prev == FREE).all(axis=1))
    return write, (cur != prev).any(axis=1)


def _slot_meshes(item, role: str, write: np.ndarray):
    """(slot index, mesh) of every slot object to write this frame; a slot object the user
    deleted is skipped with a one-time warning (its blocks are not drawn until a Rebuild)."""
    slots = field_scene.slot_objects(item, role)
    for slot in np.flatnonzero(write).tolist():
        obj = slots.get(slot)
        if obj is None:
            _warn_once(f"{role[:-1]} slot {slot} of field '{item.name}' was deleted; its blocks are not drawn "
                       "(rebuild the field to restore it)")
            continue
        yield slot, obj.data


def _position_buffer(buffer: np.ndarray | None, rows: int) -> np.ndarray:
    if buffer is None or len(buffer) != rows:
        return np.zeros((rows, 3), dtype=np.float32)
    return buffer


def _blade_colours(layout, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(RGBA (V*4,), shade (V,)) float32 per vertex of the blocks at k positions (FREE: zeros)."""
    per_blade = (layout.segments + 1) * 2
    bpb = layout.blades_per_block
    shown = blocks >= 0
    rgba = np.zeros((len(blocks), bpb, 4), dtype=np.float32)
    shade = np.zeros((len(blocks), bpb), dtype=np.float32)
    blades = blocks[shown, None].astype(np.int64) * bpb + np.arange(bpb)[None, :]
    rgba[shown, :, :3] = layout.species_color[layout.blade_species[blades]]
    rgba[shown, :, 3] = 1.0
    shade[shown] = layout.blade_shade[blades]
    return np.repeat(rgba.reshape(-1, 4), per_blade, axis=0).ravel(), np.repeat(shade.ravel(), per_blade)


def _write_blades(rt: FieldRuntime, item, lod, block_distance: np.ndarray) -> None:
    layout = rt.field.layout
    n_positions = field_scene.position_counts(layout, rt.params)[0]
    k = field_scene.blocks_per_slot(layout, rt.params)[0]
    # A block needs blades where some cell has N > 0 (eq 9).
    needs = (lod.blade_count[layout.block_cells] > 0).any(axis=1) & lod.block_visible
    current, previous, chosen = _choose_positions(rt.blade_position_block, n_positions, needs, block_distance)
    rt.blade_position_block, rt.blade_blocks = current, np.sort(chosen)
    verts_per_block = field_scene.blade_vertex_count(layout)
    shown = len(chosen) * verts_per_block  # shown blocks fill the first positions (assign_slots)
    rt.blade_buffer = buffer = _position_buffer(rt.blade_buffer, n_positions * verts_per_block)
    if len(chosen):
        rt.field.blade_vertices(current[: len(chosen)], lod=lod, out=buffer[:shown])
    buffer[shown:] = 0.0  # FREE positions: collapsed to a point, zero area, nothing drawn
    write, changed = _slot_writes(current, previous, k)
    rows = k * verts_per_block
    for slot, mesh in _slot_meshes(item, field_scene.ROLE_BLADES, write):  # one position write each
        _write_position(mesh, buffer[slot * rows:(slot + 1) * rows])
        if changed[slot]:
            # Another block at some position: its blades' colours (FREE positions cleared, so the
            # data is the same whatever the object showed before: a function of the frame alone).
            rgba, shade = _blade_colours(layout, current[slot * k:(slot + 1) * k])
            mesh.attributes[materials.ATTR_COLOR].data.foreach_set("color", rgba)
            mesh.attributes[materials.ATTR_SHADE].data.foreach_set("value", shade)
        mesh.update()


def _write_cards(rt: FieldRuntime, item, lod, block_distance: np.ndarray) -> None:
    layout = rt.field.layout
    n_positions = field_scene.position_counts(layout, rt.params)[1]
    k = field_scene.blocks_per_slot(layout, rt.params)[1]
    k_b = lod.k_billboard  # opacity of the cards, K_b of eq 7 / K'_b of eq 11
    needs = (k_b[layout.block_cells] > 0).any(axis=1) & lod.block_visible
    current, previous, chosen = _choose_positions(rt.card_position_block, n_positions, needs, block_distance)
    rt.card_position_block, rt.card_blocks = current, np.sort(chosen)
    verts_per_block = field_scene.card_vertex_count(layout)
    shown = len(chosen) * verts_per_block
    rt.card_buffer = buffer = _position_buffer(rt.card_buffer, n_positions * verts_per_block)
    # one card per cell, 4 vertices each, cells in block order; FREE positions fully transparent
    opacity = np.zeros(n_positions * verts_per_block, dtype=np.float32)
    if len(chosen):
        rt.field.card_vertices(current[: len(chosen)], out=buffer[:shown])
        opacity[:shown] = np.repeat(k_b[layout.block_cells[current[: len(chosen)]]].astype(np.float32),
                                    4, axis=1).ravel()
    buffer[shown:] = 0.0
    write, _ = _slot_writes(current, previous, k)
    rows = k * verts_per_block
    for slot, mesh in _slot_meshes(item, field_scene.ROLE_CARDS, write):
        _write_position(mesh, buffer[slot * rows:(slot + 1) * rows])
        # K_b follows the camera every frame, not only when a position changes block.
        mesh.attributes[materials.ATTR_OPACITY].data.foreach_set("value", opacity[slot * rows:(slot + 1) * rows])
        mesh.update()


def _camera_signature(camera) -> tuple | None:
    if camera is None:
        return None
    return (tuple(np.round(camera.position, 6)), tuple(np.round(camera.forward, 6)),
            tuple(np.round(camera.up, 6)), round(camera.fov_x, 6), round(camera.aspect, 6))


def _field_camera(scene, item, depsgraph=None):
    """The scene camera in the field's frame (the ground object's inverse world matrix)."""
    ground = field_scene.ground_object(item)
    if ground is not None and depsgraph is not None:
        ground = ground.evaluated_get(depsgraph)
    to_field = ground.matrix_world.inverted_safe() if ground is not None else None
    return blender_camera(scene, to_field, depsgraph)


def update_field(scene, item, depsgraph=None, camera_moved_only: bool = False) -> FieldRuntime | None:
    """Write the field ``item`` of ``scene`` for ``scene.frame_current``. Returns its runtime, or
    None when the field has no collection (not built, or deleted by hand).

    ``camera_moved_only``: skip the write when this frame was written with the same camera
    (the ``frame_change_post`` pass, see ``on_frame_change_post``)."""
    frame = scene.frame_current
    if camera_moved_only:
        rt = get_runtime(scene, item)
        if rt is None or rt.frame != frame or item.collection is None:
            return rt  # not written at this frame yet: the frame handlers will do it
        camera = _field_camera(scene, item, depsgraph)
        if rt.camera_signature == _camera_signature(camera):
            return rt  # same camera, same frame: nothing to do (cheap: no parameter read)
    rt = ensure_runtime(scene, item)
    coll = item.collection
    if coll is None:
        _warn_once(f"field '{item.name}' has no collection (deleted?); nothing to update")
        return None
    layout = rt.field.layout
    if coll.get("wg_topology") != field_scene.topology_key(layout, rt.params):
        field_scene.build_slots(scene, item, layout, rt.params)
        rt.blade_position_block = np.zeros(0, np.int32)
        rt.card_position_block = np.zeros(0, np.int32)
    camera = _field_camera(scene, item, depsgraph)
    signature = _camera_signature(camera)
    if rt.frame != frame or getattr(rt.field, "cells", None) is None:
        rt.field.seek(frame)  # a camera-only update reuses this frame's cell data
    lod = rt.field.lod(camera)
    if camera is None:
        # No camera: every block is geometry (lod_weights(None)); the pool takes the blocks
        # nearest the field centre.
        centre = 0.5 * (layout.block_bounds[:, :2] + layout.block_bounds[:, 2:])
        block_distance = np.hypot(centre[:, 0], centre[:, 1]).astype(np.float32)
    else:
        block_distance = np.asarray(lod.block_distance, dtype=np.float32)
    _write_blades(rt, item, lod, block_distance)
    _write_cards(rt, item, lod, block_distance)
    rt.frame = frame
    rt.lod = lod
    rt.camera_signature = signature
    return rt


def update_scene(scene, depsgraph=None, camera_moved_only: bool = False) -> None:
    """Write every field of ``scene`` for its current frame; never raises into Blender."""
    settings = getattr(scene, "windgrass", None)
    if settings is None:
        return
    for item in settings.fields:
        _update_guarded(scene, item, depsgraph, camera_moved_only)


def _update_guarded(scene, item, depsgraph=None, camera_moved_only: bool = False) -> None:
    """update_field, never raising: a field that cannot be simulated (a setting out of range, a
    failure) records the error for the panel and for scripts (``field_error``) and hides its
    grass, so no frame shows the grass of another frame."""
    key = runtime_key(scene, item)
    try:
        update_field(scene, item, depsgraph, camera_moved_only)
    except Exception as exc:  # a handler must not break playback or rendering
        message = str(exc) if isinstance(exc, WindgrassError) else f"{type(exc).__name__}: {exc}"
        ERRORS[key] = message
        _warn_once(f"field '{item.name}' cannot be simulated, its grass is hidden: {message}")
        try:
            _hide_field(scene, item)
        except Exception as hide_exc:  # pragma: no cover (objects gone mid-render)
            _warn_once(f"field '{item.name}' could not be hidden: {hide_exc}")
    else:
        if not camera_moved_only:  # (that pass skips fields not written at this frame)
            ERRORS.pop(key, None)


def _hide_field(scene, item) -> None:
    """Collapse every slot of the field to a point (nothing drawn) and forget what they showed."""
    for role in (field_scene.ROLE_BLADES, field_scene.ROLE_CARDS):
        for obj in field_scene.slot_objects(item, role).values():
            mesh = obj.data
            if len(mesh.vertices):
                _write_position(mesh, np.zeros((len(mesh.vertices), 3), np.float32))
                mesh.update()
    rt = get_runtime(scene, item)
    if rt is not None:
        rt.blade_position_block = np.zeros(0, np.int32)
        rt.card_position_block = np.zeros(0, np.int32)
        rt.frame = None


# Edits in the UI arrive once per slider step; they are coalesced and applied once the user pauses
# for this long, so dragging a slider on a large field does not re-simulate at every step.
_EDIT_SETTLE_S = 0.15
_PENDING: dict[tuple[str, str], float] = {}


def mark_dirty(scene, item, defer: bool | None = None) -> None:
    """Parameters of ``item`` changed: rewrite it (the digest decides what is rebuilt).

    Scripts and background renders (``bpy.app.background``) get the update at once; in the UI
    (``defer``) it waits until the edits settle (a timer), so interactive edits stay fluid.
    """
    if not (defer if defer is not None else not bpy.app.background):
        _update_now(scene, item)
        return
    _PENDING[runtime_key(scene, item)] = time.monotonic()
    if not bpy.app.timers.is_registered(_flush_pending):
        bpy.app.timers.register(_flush_pending, first_interval=_EDIT_SETTLE_S)


def _update_now(scene, item) -> None:
    if item.collection is not None:
        _update_guarded(scene, item)


def _flush_pending() -> float | None:
    """Timer: apply settled edits; run again shortly while the user is still dragging."""
    latest = max(_PENDING.values(), default=0.0)
    wait = latest + _EDIT_SETTLE_S - time.monotonic()
    if wait > 0:
        return wait
    pending = list(_PENDING)
    _PENDING.clear()
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    for scene_uid, uid in pending:
        scene = scenes.get(scene_uid)
        item = next((f for f in scene.windgrass.fields if f.uid == uid), None) if scene else None
        if item is not None:
            _update_now(scene, item)
    return None


def reset_field(scene, item) -> None:
    """Forget the runtime of ``item`` so it is re-simulated from its parameters."""
    RUNTIMES.pop(runtime_key(scene, item), None)


# --------------------------------------------------------------------------------------------
# Handlers


@persistent
def on_frame_change_pre(scene, depsgraph=None):
    """Simulate and write the new frame (the contract's handler)."""
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
    if not RUNTIMES or bpy.app.is_job_running("RENDER"):
        return
    update_scene(scene, depsgraph, camera_moved_only=True)


@persistent
def on_load_post(*_args):
    RUNTIMES.clear()
    ERRORS.clear()
    _WARNED.clear()
    _PENDING.clear()


@persistent
def on_undo_redo_post(*_args):
    """Undo and redo bring back older mesh data: forget what the slots show, so the next
    update rewrites every slot (positions and colours) instead of trusting stale state."""
    for rt in RUNTIMES.values():
        rt.blade_position_block = np.zeros(0, np.int32)
        rt.card_position_block = np.zeros(0, np.int32)


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
    """Add the handlers exactly once (also after a reload of the add-on)."""
    for handlers, func in _HANDLERS:
        for existing in [h for h in handlers if _same(h, func)]:
            handlers.remove(existing)
        handlers.append(func)


def unregister() -> None:
    for handlers, func in _HANDLERS:
        for existing in [h for h in handlers if _same(h, func)]:
            handlers.remove(existing)
    if bpy.app.timers.is_registered(_flush_pending):
        bpy.app.timers.unregister(_flush_pending)
    _PENDING.clear()
    RUNTIMES.clear()
    ERRORS.clear()
    _WARNED.clear()
