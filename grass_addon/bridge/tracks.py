"""Colliders and force fields of a field in Blender: their motion sampled once per frame.

A collider moves by keys, constraints, parents or an armature; only the evaluated scene knows
where it is, and only at the current frame. So the motion is sampled once, frame by frame over
the range the grass can show (``frame_range``: the recovery, or the simulation's warm-up, before
the scene's start, to its end), and stored on the field's collection (``TRACK_KEY``): frame N is
then a function of the stored track and N, a render or a farm node reads the same track, and a
.blend rendered without the window still has it. It is made again when what it was sampled from
changes (``fingerprint``: the objects, their keys, constraints, parents, armatures and field
settings) — by the panel's Update Motion (``windgrass.track_update``), and in the window by a
timer once the edits settle.

Colliders become spheres (``collider_shapes.spheres_of``): the part of the object's evaluated mesh below the
grass's top, cut into pieces at most ``CLUSTER`` wide, each in its bounding sphere (a ball is
itself, a foot one sphere, a car or a wall a row of them). Force fields become
``forces.Effector`` with Blender's own settings; their transform and strength are sampled per
frame, so a field switched on at a frame (its strength keyed) acts from that frame.
"""

from __future__ import annotations

import hashlib
import json
import math
from typing import Any

import bpy
import numpy as np

from .. import collider_shapes, forces
from ..clock import Clock
from ..errors import ParameterError
from ..interaction import SampledTrack
from ..schema import Params
from . import maps, owned
from .animation import action_fcurves, fcurve_fingerprint
from .registry import REGISTRY, key_of

TRACK_KEY = "wg_track"
BLENDER_TYPES = {"WIND": "wind", "FORCE": "force", "VORTEX": "vortex", "TURBULENCE": "turbulence"}
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}
CLUSTER = 0.8  # m: a collider's part near the ground is cut into pieces at most this wide, a sphere each


# --------------------------------------------------------------------------------------------
# What a field's motion is read from


def collider_objects(item) -> list:
    """The objects of the field's Colliders collection that have geometry, never the field's own;
    none when it holds none (an emptied collection means no colliders: ``notes`` says so)."""
    coll = item.collider_collection
    if coll is None:
        return []
    own = {o.name for o in owned.field_objects(item)}
    return [o for o in coll.all_objects if o.name not in own and o.type in GEOMETRY_TYPES]


def _field_type(obj) -> str:
    return obj.field.type if getattr(obj, "field", None) is not None else "NONE"


def effector_objects(item) -> list:
    """The force fields of the field's Force Fields collection that the grass feels (Wind, Force,
    Vortex, Turbulence); others and objects with no field are left out (``notes`` says so)."""
    coll = item.effector_collection
    if coll is None:
        return []
    return [obj for obj in coll.all_objects if _field_type(obj) in BLENDER_TYPES]


def notes(item) -> list[str]:
    """Sentences for the panel about what the field's collections give it: an emptied Colliders
    collection, the field's own collection picked, force fields the grass does not feel."""
    out = []
    coll = item.collider_collection
    if coll is not None and not collider_objects(item):
        if item.collection is not None and coll.name == item.collection.name:
            out.append(f"'{coll.name}' is this field's own collection: it has no colliders (pick the collection "
                       "of the objects that move through the grass)")
        else:
            kinds = ", ".join(sorted({o.type.lower() for o in coll.all_objects})) or "nothing"
            out.append(f"The Colliders collection '{coll.name}' holds {kinds}: no colliders (colliders are objects "
                       "with geometry: a mesh, a curve, text, metaballs)")
    coll = item.effector_collection
    if coll is not None:
        felt = ", ".join(t.title() for t in BLENDER_TYPES)
        for obj in coll.all_objects:
            kind = _field_type(obj)
            if kind not in BLENDER_TYPES and kind != "NONE":
                out.append(f"'{obj.name}' is a {kind.title()} force field, which the grass does not feel ({felt})")
        for obj in effector_objects(item):
            up = obj.matrix_world.col[2][2] / max(obj.matrix_world.col[2].length, 1e-12)
            if _field_type(obj) == "WIND" and abs(up) > VERTICAL_WIND:
                way = "up" if up > 0 else "down"
                out.append(f"'{obj.name}' blows along its Z axis, which points {way}: the grass hardly moves; rotate "
                           "it to blow across the grass (e.g. 90 degrees about X)")
        if not effector_objects(item):
            out.append(f"The Force Fields collection '{coll.name}' holds no force field the grass feels ({felt})")
    return out


VERTICAL_WIND = math.cos(math.radians(25.0))  # a Wind within 25 degrees of straight up or down (as Blender adds one)


def frame_range(scene, params: Params) -> range:
    """The frames sampled: the recovery (or the simulation's warm-up) before the start, to the end."""
    fps = Clock.of(params).rate
    before = max(math.ceil(params.interaction.recovery * fps), math.ceil(params.simulation.preroll * fps))
    return range(int(scene.frame_start) - before, int(scene.frame_end) + 1)


def _animation(obj, seen: set) -> list:
    """What moves ``obj``: its keys, constraints (and their targets), parent and modifiers' objects."""
    if obj is None or obj.name in seen:
        return []
    seen.add(obj.name)
    out = [obj.name, obj.type]
    keyed = False
    for owner in (obj, getattr(obj, "data", None)):
        for fc in action_fcurves(getattr(owner, "animation_data", None)):
            out.append([fc.data_path, fc.array_index, hashlib.sha1(fcurve_fingerprint(fc)).hexdigest(), fc.mute])
            keyed = True
    if not keyed:  # (a keyed object's pose changes with the frame; its keys say where it goes)
        out.append([round(v, 6) for row in obj.matrix_basis for v in row])
    for con in obj.constraints:
        out.append([con.type, con.mute, con.influence])
        out.extend(_animation(getattr(con, "target", None), seen))
    out.extend(_animation(obj.parent, seen))
    for mod in getattr(obj, "modifiers", ()):
        out.append([mod.type, mod.show_render])
        out.extend(_animation(getattr(mod, "object", None), seen))
    if obj.type == "MESH":
        out.append(len(obj.data.vertices))
    if obj.type == "ARMATURE" and obj.pose is not None and not keyed:
        out.append([[round(v, 5) for v in (*b.location, *b.rotation_quaternion)] for b in obj.pose.bones])
    return out


# forces.Effector's settings read from Blender's field settings: (its field, Blender's, type, default).
FIELD_SETTINGS = (
    ("strength", "strength", float, 0.0), ("power", "falloff_power", float, 0.0),
    ("min_distance", "distance_min", float, 0.0), ("use_min", "use_min_distance", bool, False),
    ("max_distance", "distance_max", float, 0.0), ("use_max", "use_max_distance", bool, False),
    ("radial_power", "radial_falloff", float, 0.0), ("radial_min", "radial_min", float, 0.0),
    ("use_radial_min", "use_radial_min", bool, False), ("radial_max", "radial_max", float, 0.0),
    ("use_radial_max", "use_radial_max", bool, False), ("noise", "noise", float, 0.0),
    ("size", "size", float, 1.0), ("seed", "seed", int, 1),
)


def _field_settings(obj) -> list:
    """What a force field acts with, as the sampling reads it; a keyed setting is left to its
    keys (its value changes with the frame; ``_animation`` reads the keys)."""
    f = obj.field
    keyed = {fc.data_path for fc in action_fcurves(obj.animation_data)}
    return [f.type, f.shape, f.falloff_type] + [getattr(f, name, default) for _, name, _, default in FIELD_SETTINGS
                                                 if f"field.{name}" not in keyed]


def fingerprint(scene, item, params: Params) -> str:
    """What the stored track was sampled from: the frame range, the grass's reach and every
    collider's and force field's motion and settings."""
    colliders, effectors = collider_objects(item), effector_objects(item)
    if not colliders and not effectors:
        return ""
    frames = frame_range(scene, params)
    seen: set = set()
    rate = int(params.render.fps) if params.render.fps_base == 1.0 else Clock.of(params).rate
    data = [frames.start, frames.stop, rate, _top(params), params.field.cell_size,
            maps.terrain_key(scene, item, params),
            [_animation(o, seen) for o in colliders],
            [[_animation(o, seen), _field_settings(o)] for o in effectors]]
    ground = owned.ground_object(item)
    if ground is not None:
        data.append([round(v, 6) for row in ground.matrix_world for v in row])
    return hashlib.sha1(json.dumps(data, default=str).encode()).hexdigest()


def _top(params: Params) -> float:
    """How high above the ground grass can reach (the longest species, twice as long by a length map)."""
    return 2.0 * max(float(sp["length"]) for sp in params.species())


# --------------------------------------------------------------------------------------------
# Sampling


def _object_points(obj_eval, matrix: np.ndarray, islands_of: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The evaluated object's vertices and triangle centres (k, 3) through ``matrix`` (its own
    frame to the one wanted), and the island of each (k,); ``islands_of`` keeps each mesh's
    islands between frames (a deforming mesh keeps its topology)."""
    mesh = obj_eval.to_mesh()
    try:
        n = len(mesh.vertices)
        co: np.ndarray = np.empty(n * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3).astype(np.float64)
        key = (obj_eval.name, n, len(mesh.edges), len(mesh.polygons))
        islands = None if islands_of is None else islands_of.get(key)
        if islands is None:
            edges = np.empty(len(mesh.edges) * 2, np.int64)
            mesh.edges.foreach_get("vertices", edges)
            islands = collider_shapes.mesh_islands(n, edges.reshape(-1, 2))
            if islands_of is not None:
                islands_of[key] = islands
        mesh.calc_loop_triangles()
        tris: np.ndarray = np.empty(len(mesh.loop_triangles) * 3, np.int64)
        mesh.loop_triangles.foreach_get("vertices", tris)
    finally:
        obj_eval.to_mesh_clear()
    if len(tris):
        tris = tris.reshape(-1, 3)
        co = np.concatenate([co, co[tris].mean(axis=1)])
        islands = np.concatenate([islands, islands[tris[:, 0]]])
    m = np.asarray(matrix, np.float64)
    return co @ m[:3, :3].T + m[:3, 3], islands


RIGID_MIN_VERTICES = 20_000  # a rigid collider this large is cut into pieces once (RigidPieces)
SECONDS_PER_FRAME = 0.005  # measured (dev.py bench --motion): a frame stepped and its rigid colliders moved
SECONDS_PER_VERTEX = 1.5e-6  # and per vertex of a collider whose mesh is read every frame
AUTO_SAMPLE_S = 2.0  # the window samples again by itself only when it takes about this long at most


def sampling_seconds(scene, item, params: Params) -> float:
    """About how long sampling the field's motion takes: the frames, and the vertices of the
    colliders whose meshes are read every frame (not the large rigid ones)."""
    read = sum(len(o.data.vertices) if o.type == "MESH" else 10_000 for o in collider_objects(item)
               if not (rigid(o) and len(o.data.vertices) >= RIGID_MIN_VERTICES))
    return len(frame_range(scene, params)) * (SECONDS_PER_FRAME + SECONDS_PER_VERTEX * read)


def rigid(obj) -> bool:
    """Whether only ``obj``'s matrix moves it (keys, constraints, a parent or a bone): a mesh with
    no modifiers, shape keys or animated mesh data, whose shape in its own frame never changes."""
    if obj.type != "MESH" or len(obj.modifiers) or obj.data.shape_keys is not None:
        return False
    return not action_fcurves(getattr(obj.data, "animation_data", None))


class _Sampler:
    """One frame's spheres of each collider: rigid large ones from pieces cut once, the others
    from their evaluated mesh (the islands of each mesh found once)."""

    def __init__(self, colliders, to_field, top_z):
        self.colliders, self.to_field, self.top_z = colliders, to_field, top_z
        self.pieces: dict[int, collider_shapes.RigidPieces] = {}
        self.islands: dict = {}

    def spheres(self, j: int, obj_eval) -> tuple:
        obj = self.colliders[j]
        world = self.to_field @ np.array(obj_eval.matrix_world, np.float64)
        if j in self.pieces or (rigid(obj) and len(obj.data.vertices) >= RIGID_MIN_VERTICES):
            if j not in self.pieces:
                local, islands = _object_points(obj_eval, np.eye(4), self.islands)
                self.pieces[j] = collider_shapes.RigidPieces(local, islands, CLUSTER)
            return self.pieces[j].at(world, self.top_z)
        points, islands = _object_points(obj_eval, world, self.islands)
        centres, radii = collider_shapes.spheres_of(points, CLUSTER, self.top_z, islands)
        return centres, radii, points.mean(axis=0) if len(points) else np.zeros(3)


def _effector(obj_eval, to_field: np.ndarray) -> forces.Effector:
    f = obj_eval.field
    settings: dict[str, Any] = {key: kind(getattr(f, name, default)) for key, name, kind, default in FIELD_SETTINGS}
    return forces.Effector(
        kind=BLENDER_TYPES[f.type], matrix=to_field @ np.array(obj_eval.matrix_world, np.float64),
        shape="plane" if f.shape == "PLANE" else "point",
        falloff_type={"TUBE": "tube", "CONE": "cone"}.get(f.falloff_type, "sphere"), **settings)


def _blender_perlin(p: np.ndarray) -> np.ndarray:
    """(m,) Blender's own improved Perlin noise (the noise its Turbulence field reads) of points (m, 3)."""
    from mathutils import noise

    return np.fromiter((noise.noise(v, noise_basis="PERLIN_NEW") for v in p.tolist()), np.float64, len(p))


def blender_turbulence(q: np.ndarray) -> np.ndarray:
    """``forces.turbulence_vector`` with Blender's noise: a Turbulence acts on the grass as on
    Blender's particles (read a point at a time, about 1 us; the engine keeps what a still one gives)."""
    return forces.turbulence_vector(q, noise=_blender_perlin)


def sample(scene, item, params: Params, progress=None) -> dict:
    """Sample the field's colliders and force fields at every frame of ``frame_range``: the
    track to store (``store``). ``progress(done, total)`` after each frame. The scene is back at
    its frame afterwards."""
    steps = sampling(scene, item, params)
    while True:
        try:
            done, total = next(steps)
        except StopIteration as finished:
            return finished.value
        if progress is not None:
            progress(done, total)


def sampling(scene, item, params: Params):
    """``sample`` a frame at a time: a generator yielding (done, total) after each frame and
    returning the track; closed early (Esc), it puts the scene back at its frame and keeps nothing."""
    colliders, effectors = collider_objects(item), effector_objects(item)
    ground = owned.ground_object(item)
    to_field = np.array(ground.matrix_world.inverted_safe(), np.float64) if ground is not None else np.eye(4)
    state = REGISTRY.states.get(key_of(scene, item))
    kept = None if state is None else state.terrain  # (terrain key, heightfield, centre)
    ground_top = float(kept[1].heights.max()) if kept is not None and kept[1] is not None else 0.0
    sampler = _Sampler(colliders, to_field, ground_top + _top(params))
    frames = frame_range(scene, params)
    clock = Clock.of_scene(scene)
    fps = clock.rate
    frame, subframe = scene.frame_current, scene.frame_subframe
    per_object: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = [[] for _ in colliders]
    fields: list[list[dict]] = []
    REGISTRY.sampling = True
    try:
        for i, f in enumerate(frames):
            scene.frame_set(f)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            for j, obj in enumerate(colliders):
                per_object[j].append(sampler.spheres(j, obj.evaluated_get(depsgraph)))
            fields.append([_effector_dict(_effector(o.evaluated_get(depsgraph), to_field)) for o in effectors])
            yield i + 1, len(frames)  # (the handlers stay out until the scene is back at its frame)
    finally:
        scene.frame_set(frame, subframe=subframe)
        REGISTRY.sampling = False
    times = [clock.seconds(f) for f in frames]
    offsets, centres, radii, velocity = [0], [], [], []
    for k in range(len(frames)):
        for j in range(len(colliders)):
            c, r, _ = per_object[j][k]
            before, after = per_object[j][max(k - 1, 0)][2], per_object[j][min(k + 1, len(frames) - 1)][2]
            span = (min(k + 1, len(frames) - 1) - max(k - 1, 0)) / fps
            v = (after - before)[:2] / span if span > 0 else np.zeros(2)
            centres.append(c)
            radii.append(r)
            velocity.append(np.tile(v, (len(r), 1)))
        offsets.append(offsets[-1] + sum(len(per_object[j][k][1]) for j in range(len(colliders))))
    cat = lambda parts, width: np.concatenate(parts) if parts else np.zeros((0, width))  # noqa: E731
    return {"times": times, "offsets": offsets, "centres": cat(centres, 3).reshape(-1).tolist(),
            "radii": cat([r[:, None] for r in radii], 1).reshape(-1).tolist(),
            "velocity": cat(velocity, 2).reshape(-1).tolist(), "colliders": len(colliders),
            "effectors": json.dumps(fields) if effectors else ""}


def _effector_dict(e: forces.Effector) -> dict:
    out = {k: getattr(e, k) for k in e.__dataclass_fields__ if k != "matrix"}
    out["matrix"] = [round(float(v), 7) for v in np.asarray(e.matrix).reshape(-1)]
    return out


def store(item, track: dict, digest: str) -> None:
    """Keep the track with the file, on the field's collection."""
    item.collection[TRACK_KEY] = {**track, "fingerprint": digest}
    REGISTRY.tracks.pop(digest, None)  # (a damaged track of the same fingerprint was decoded before)


def clear(item) -> None:
    if item.collection is not None and TRACK_KEY in item.collection:
        del item.collection[TRACK_KEY]


def stored(item):
    """(colliders [SampledTrack] or [], effectors SampledEffectors or None, fingerprint) of the
    stored track; ([], None, '') without one, or when it is damaged (``damage`` says how: the
    panel asks for Update Motion, which samples it again) or its colliders are gone."""
    coll = item.collection
    raw = coll.get(TRACK_KEY) if coll is not None else None
    if raw is None or (not collider_objects(item) and not effector_objects(item)):
        return [], None, ""  # (the motion of colliders since deleted or moved out moves no grass)
    colliders, effectors, broken = _decoded(raw)
    if broken:
        return [], None, ""
    return colliders, effectors, str(raw.get("fingerprint", ""))


def _decoded(raw) -> tuple:
    """(colliders, effectors, how it is damaged or '') of a stored track, decoded once per
    fingerprint (``REGISTRY.tracks``; ``store`` drops the entry of the fingerprint it writes)."""
    if not _is_table(raw):
        return [], None, f"unreadable: a {type(raw).__name__}, not the table Update Motion stores"
    digest = str(raw.get("fingerprint", ""))
    cached = REGISTRY.tracks.get(digest)
    if cached is None:
        try:
            cached = _decode(raw)
        except DamagedTrackError as exc:
            cached = ([], None, str(exc))
        except (TypeError, ValueError, KeyError, AttributeError, IndexError) as exc:
            # a value of a shape no check above foresaw (the file was edited by hand): damage too
            cached = ([], None, f"unreadable: {type(exc).__name__}: {exc}")
        REGISTRY.tracks[digest] = cached
    return cached


def _is_table(raw) -> bool:
    """The stored motion is a table (an ID property group), not a number, a text or a list that a
    file edited by hand left there."""
    return callable(getattr(raw, "get", None)) and callable(getattr(raw, "keys", None))


class DamagedTrackError(ValueError):
    """A stored track that cannot be what ``sample`` wrote (a file edited or broken by hand)."""


MAX_RADIUS = 1000.0  # m: a stored sphere wider than this is damage, not a collider


def _numbers(raw, key: str, size: int | None = None, kind=np.float64) -> np.ndarray:
    """The stored list ``key`` as finite numbers (``size`` of them when given), else DamagedTrackError."""
    try:
        values = np.asarray(list(raw[key]), dtype=np.float64)
    except (KeyError, TypeError, ValueError) as exc:
        raise DamagedTrackError(f"'{key}' is not a list of numbers ({type(exc).__name__})") from None
    if values.ndim != 1 or (size is not None and len(values) != size) or not np.isfinite(values).all():
        raise DamagedTrackError(f"'{key}' has {len(values)} values, not finite or not {size}")
    return values.astype(kind)


def _decode(raw) -> tuple:
    """(colliders, effectors, '') of a stored track, every list checked against the others
    (lengths, finite numbers, radii within MAX_RADIUS, known effector settings)."""
    times = _numbers(raw, "times")
    if len(times) and np.any(np.diff(times) <= 0):
        raise DamagedTrackError("'times' is not ascending")
    colliders = []
    try:
        count = int(raw.get("colliders", 0) or 0)
    except (TypeError, ValueError):
        raise DamagedTrackError("'colliders' is not a count") from None
    if count:
        offsets = _numbers(raw, "offsets", len(times) + 1)
        if np.any(offsets != np.round(offsets)):
            raise DamagedTrackError("'offsets' are not whole counts")
        offsets = offsets.astype(np.int64)
        if offsets[0] != 0 or np.any(np.diff(offsets) < 0):
            raise DamagedTrackError("'offsets' is not a running count")
        spheres = int(offsets[-1])
        radii = _numbers(raw, "radii", spheres)
        if np.any(radii <= 0.0) or np.any(radii > MAX_RADIUS):
            raise DamagedTrackError(f"a radius outside 0-{MAX_RADIUS:g} m")
        colliders = [SampledTrack(times, offsets, _numbers(raw, "centres", 3 * spheres), radii,
                                  _numbers(raw, "velocity", 2 * spheres))]
    effectors = None
    text = raw.get("effectors", "") or ""
    if text:
        try:
            rows = json.loads(str(text))
            if not isinstance(rows, list):
                raise DamagedTrackError("the force fields' samples are not a list")
            samples = [[_stored_effector(e) for e in sample] for sample in rows]
        except DamagedTrackError:
            raise
        except (TypeError, ValueError, AttributeError) as exc:
            raise DamagedTrackError(f"the force fields' samples: {exc}") from None
        if len(samples) != len(times):
            raise DamagedTrackError(f"{len(samples)} force-field samples for {len(times)} times")
        effectors = forces.SampledEffectors(times, samples, turbulence=blender_turbulence)
    return colliders, effectors, ""


def _stored_effector(e: dict) -> forces.Effector:
    """One stored force field, every setting known and finite (else DamagedTrackError)."""
    fields = forces.Effector.__dataclass_fields__
    if not isinstance(e, dict) or set(e) - set(fields) or e.get("kind") not in ("wind", "force", "vortex",
                                                                                 "turbulence"):
        raise DamagedTrackError("a force field with unknown settings")
    matrix = np.asarray(e.get("matrix"), np.float64).reshape(4, 4)
    numbers = [v for k, v in e.items() if k not in ("kind", "matrix", "shape", "falloff_type")]
    if not np.isfinite(matrix).all() or not all(isinstance(v, (int, float)) and np.isfinite(v) for v in numbers):
        raise DamagedTrackError("a force field's setting is not a finite number")
    return forces.Effector(**{**e, "matrix": matrix})


def damage(item) -> str | None:
    """How the field's stored track is damaged, or None (no track, or a sound one)."""
    raw = item.collection.get(TRACK_KEY) if item.collection is not None else None
    return (_decoded(raw)[2] or None) if raw is not None else None


def stored_fingerprint(item) -> str | None:
    """The fingerprint the stored track was sampled with (None without a track, or a damaged one:
    it is sampled again)."""
    raw = item.collection.get(TRACK_KEY) if item.collection is not None else None
    if raw is None or _decoded(raw)[2]:
        return None
    return str(raw.get("fingerprint", ""))


def effector_digest(item) -> str:
    """Changes only when the stored force fields do (their part of the track)."""
    coll = item.collection
    raw = coll.get(TRACK_KEY) if coll is not None else None
    text = str(raw.get("effectors", "") or "") if raw is not None and _is_table(raw) else ""
    return hashlib.sha1(text.encode()).hexdigest() if text else ""


def status(scene, item, params: Params) -> str | None:
    """A line for the panel: what the stored motion is, or that it is out of date."""
    try:
        wanted = fingerprint(scene, item, params)
    except ParameterError as exc:
        return str(exc)
    if not wanted:
        return None
    broken = damage(item)
    if broken:
        coll = item.collider_collection or item.effector_collection
        return f"The stored motion of '{coll.name}' is damaged ({broken}): press Update Motion"
    if stored_fingerprint(item) != wanted:
        seconds = sampling_seconds(scene, item, params)
        long = f" (about {seconds:.0f} s; Esc stops it)" if seconds > AUTO_SAMPLE_S else ""
        return f"Motion of the colliders and force fields not sampled yet: press Update Motion{long}"
    frames = len(item.collection[TRACK_KEY]["times"])
    return f"Motion sampled over {frames} frames ({frames / Clock.of(params).rate:.1f} s)"
