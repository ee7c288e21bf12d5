"""Peer benchmark: our frame against Geometry Nodes wind and hair dynamics, same blade count.

    python headless/bench_peers.py [--blades 10000 100000] [--frames N] [--no-ours] [--peers ...]

prints one JSON object; ``headless/bench.py --peers`` imports ``run_peers`` and stores the same
dict under the key "peers". For each blade count every peer runs in a fresh empty scene:

* ``ours``: a Windgrass field added through the add-on (``bpy.ops.windgrass.field_add`` with the
  blocks of ``field_plan``), LOD off, so every blade is strip geometry (5 segments, 12 vertices)
  written by our ``frame_change_pre`` handler with ``foreach_set``.
* ``ours_strips``: the same field with one plain grass (no flowers, no leaves at the stems' foot:
  no Geometry Nodes instances of ours), drawing what the Geometry Nodes peers draw.
* ``geometry_nodes``: a GN modifier builds exactly N points (Points node, random positions over the
  same area), instances a 5-segment blade strip (12 vertices, the same topology as ours), leans
  each instance and bends its vertices by a Noise Texture sampled once per blade at the root +
  a wind drift * scene time, then Realize Instances, so the result is real geometry too. This is
  the cheapest sound GN wind: the strongest peer, and the one ``ratio_ours_to_gn`` uses.
* ``geometry_nodes_vertex_noise``: the same, but the bend samples the noise at every realized
  vertex (the common tutorial recipe; likely what the issue's ~850 ms at 100k measured).
* ``hair_dynamics``: a HAIR particle system with N strands of 5 segments (``hair_step = 5``),
  ``use_hair_dynamics = True`` (default cloth settings) and a Wind force field; the cloth solver
  needs consecutive frames from the cache start, so frames are stepped forward one by one.

Timing: ``scene.frame_set(f)`` (which evaluates the depsgraph) plus a read of the evaluated
geometry's size, so the evaluation is known to have happened. Frame 1 is the untimed warm-up
(the first GN evaluation, the hair cache start; our preroll already ran in ``field_rebuild``);
frames 2 .. frames+1 are timed and the median is reported. "detail" holds every frame time, the
split into Python frame handlers vs depsgraph evaluation, and ``motion_m``: an untimed check that
the evaluated geometry really moves between two later frames.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))  # (Blender's -P does not put the script's folder on the path)
import common  # noqa: E402


def _prepare_blender_env() -> None:
    """Blender writes user files to temp dirs, set before the first ``import bpy``."""
    if "bpy" in sys.modules:
        return
    tmp = Path(tempfile.mkdtemp(prefix="windgrass-bench-peers-"))
    (tmp / "home").mkdir()
    os.environ.setdefault("BLENDER_USER_RESOURCES", str(tmp / "blender-user"))
    os.environ["HOME"] = str(tmp / "home")


# --------------------------------------------------------------------------------------------
# Shared setup: blade count -> the same field for every peer


def field_plan(blades: int) -> dict[str, Any]:
    """Blocks of our default layout whose blade total is closest to ``blades``; every peer uses it.

    A block has ``cells_per_block**2 * blades_per_cell`` blades (512 by default), so the
    real count is a multiple of that (10 000 -> 10 240, 100 000 -> 100 352). The blade size,
    segments, cell size and wind come from the schema defaults (the single source of truth).
    """
    common.load()
    from windgrass.grass_addon import schema

    p = schema.defaults()
    species = p.species()[0]
    per_block = p.field.cells_per_block ** 2 * p.field.blades_per_cell
    n_blocks = max(1, round(blades / per_block))
    blocks_x = max(1, round(math.sqrt(n_blocks)))
    blocks_y = max(1, round(n_blocks / blocks_x))
    block_size = p.field.cells_per_block * p.field.cell_size
    return {
        "requested": int(blades),
        "blades": blocks_x * blocks_y * per_block,
        "blocks_x": blocks_x,
        "blocks_y": blocks_y,
        "size_x": blocks_x * block_size,
        "size_y": blocks_y * block_size,
        "segments": int(p.blade.segments),
        "length": float(species["length"]),
        "width": float(species["width"]),
        "wind_speed": float(p.wind.speed),
        "wind_direction_deg": float(p.wind.direction),
    }


def _fresh_scene():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start = 1
    scene.frame_end = 100_000
    return scene


class _Stamps:
    """Our own frame handlers around everyone else's: how a frame splits into Python handlers
    (``frame_change_pre``, where our engine runs) and depsgraph evaluation (until ``_post``)."""

    def __init__(self) -> None:
        self.t: dict[str, float] = {}

    def pre_first(self, *_args) -> None:
        self.t["pre_start"] = time.perf_counter()

    def pre_last(self, *_args) -> None:
        self.t["pre_end"] = time.perf_counter()

    def post_first(self, *_args) -> None:
        self.t["post"] = time.perf_counter()

    def install(self) -> None:
        import bpy

        h = bpy.app.handlers
        h.frame_change_pre.insert(0, self.pre_first)
        h.frame_change_pre.append(self.pre_last)
        h.frame_change_post.insert(0, self.post_first)

    def remove(self) -> None:
        import bpy

        h = bpy.app.handlers
        for handlers, fn in ((h.frame_change_pre, self.pre_first), (h.frame_change_pre, self.pre_last),
                             (h.frame_change_post, self.post_first)):
            if fn in handlers:
                handlers.remove(fn)


def _time_frames(scene, frames: int, check: Callable[[], int]) -> dict[str, Any]:
    """Warm-up at frame 1, then time ``frame_set`` of frames 2 .. frames+1 (stepping forward)."""
    t0 = time.perf_counter()
    scene.frame_set(1)
    count = check()
    warmup_ms = (time.perf_counter() - t0) * 1e3
    times, handlers, evaluation = [], [], []
    stamps = _Stamps()
    stamps.install()
    try:
        for f in range(2, frames + 2):
            stamps.t.clear()
            t0 = time.perf_counter()
            scene.frame_set(f)
            count = check()
            times.append((time.perf_counter() - t0) * 1e3)
            t = stamps.t
            if len(t) == 3:
                handlers.append((t["pre_end"] - t["pre_start"]) * 1e3)
                evaluation.append((t["post"] - t["pre_end"]) * 1e3)
    finally:
        stamps.remove()
    out = {
        "median_ms": statistics.median(times),
        "mean_ms": statistics.fmean(times),
        "frame_ms": [round(t, 2) for t in times],
        "warmup_ms": round(warmup_ms, 1),
        "evaluated_vertices": int(count),
    }
    if handlers:  # split of the median: Python frame handlers vs depsgraph evaluation
        out["handlers_ms"] = round(statistics.median(handlers), 2)
        out["evaluation_ms"] = round(statistics.median(evaluation), 2)
    return out


def _motion(scene, frames: int, sample: Callable[[], Any]) -> float:
    """Untimed proof that the peer animates: the largest displacement (m) of sampled evaluated
    points between the two frames after the timed ones."""
    import numpy as np

    scene.frame_set(frames + 2)
    a = np.asarray(sample(), dtype=np.float64)
    scene.frame_set(frames + 3)
    b = np.asarray(sample(), dtype=np.float64)
    return round(float(np.abs(b - a).max()), 5) if a.size and a.shape == b.shape else 0.0


def _mesh_sample(objects, limit: int = 6144) -> Callable[[], Any]:
    """The first ``limit`` evaluated vertex positions of the first object."""
    import bpy
    import numpy as np

    def sample():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        mesh = objects[0].evaluated_get(depsgraph).data
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        return co.reshape(-1, 3)[:limit]

    return sample


def _evaluated_vertex_count(obj) -> Callable[[], int]:
    import bpy

    def check() -> int:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        return len(obj.evaluated_get(depsgraph).data.vertices)

    return check


def _ground_plane(name: str, plan: dict[str, Any]):
    """A one-face plane covering the field (the emitter of the hair, the host of the GN modifier)."""
    import bpy

    hx, hy = plan["size_x"] / 2, plan["size_y"] / 2
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)], [], [(0, 1, 2, 3)])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


# --------------------------------------------------------------------------------------------
# Peer (b): Geometry Nodes field with Noise-Texture wind, realized


def build_geometry_nodes_tree(plan: dict[str, Any], per_vertex: bool = False):
    """Points (exact N) -> instance a 12-vertex blade strip, leaned by noise -> realize -> bend by noise.

    The wind is a Noise Texture at the blade root + a drift of ``wind_speed * seconds`` along the
    wind direction (Scene Time node, so the modifier re-evaluates every frame). It is sampled
    once per blade on the points, stored as attribute "wind", carried through the instances
    into the realized vertices, and used twice: a lean of the whole instance (rotation) and a
    bend offset growing with (z / L)^2 along the blade. This is the cheapest sound GN wind (the
    strongest peer). ``per_vertex=True`` is the other common recipe: the bend samples the noise
    again at every realized vertex (12 noise evaluations per blade instead of one).
    """
    import bpy

    tree = bpy.data.node_groups.new("PeerGrassWind", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    link = links.new

    def node(kind: str, **inputs: Any):
        n = nodes.new(kind)
        for key, value in inputs.items():
            n.inputs[key].default_value = value
        return n

    def math_node(op: str, a=None, b=None, vector=False):
        n = nodes.new("ShaderNodeVectorMath" if vector else "ShaderNodeMath")
        n.operation = op
        for i, v in enumerate((a, b)):
            if v is None:
                continue
            if isinstance(v, bpy.types.NodeSocket):
                link(v, n.inputs[i])
            else:
                n.inputs[i].default_value = v
        return n

    nodes.new("NodeGroupInput")
    out = nodes.new("NodeGroupOutput")

    # N points at random positions over the field (exact count, like our blades)
    hx, hy = plan["size_x"] / 2, plan["size_y"] / 2
    rand = nodes.new("FunctionNodeRandomValue")
    rand.data_type = "FLOAT_VECTOR"
    rand.inputs["Min"].default_value = (-hx, -hy, 0.0)
    rand.inputs["Max"].default_value = (hx, hy, 0.0)
    rand.inputs["Seed"].default_value = 7
    points = node("GeometryNodePoints", Count=plan["blades"])
    link(rand.outputs["Value"], points.inputs["Position"])

    # wind: noise at position + drift * time, centred on 0 (Color - 0.5)
    scene_time = nodes.new("GeometryNodeInputSceneTime")
    d = math.radians(plan["wind_direction_deg"])
    drift = nodes.new("ShaderNodeCombineXYZ")
    for axis, comp in (("X", math.cos(d)), ("Y", math.sin(d))):
        m = math_node("MULTIPLY", scene_time.outputs["Seconds"], -plan["wind_speed"] * comp)
        link(m.outputs[0], drift.inputs[axis])
    position = nodes.new("GeometryNodeInputPosition")
    sample_at = math_node("ADD", position.outputs["Position"], drift.outputs["Vector"], vector=True)
    noise = node("ShaderNodeTexNoise", Scale=0.15, Detail=2.0)
    link(sample_at.outputs["Vector"], noise.inputs["Vector"])
    centred = math_node("SUBTRACT", noise.outputs["Color"], (0.5, 0.5, 0.5), vector=True)
    centred = math_node("MULTIPLY", centred.outputs["Vector"], (1.0, 1.0, 0.0), vector=True)  # horizontal
    store = node("GeometryNodeStoreNamedAttribute", Name="wind")
    store.data_type = "FLOAT_VECTOR"
    store.domain = "POINT"
    link(points.outputs["Points"], store.inputs["Geometry"])
    link(centred.outputs["Vector"], store.inputs["Value"])

    # the blade: a 2 x (segments+1) grid standing on its root = 12 vertices, 5 quads
    length, width = plan["length"], plan["width"]
    grid = node("GeometryNodeMeshGrid", **{"Size X": width, "Size Y": length, "Vertices X": 2,
                                           "Vertices Y": plan["segments"] + 1})
    stand = node("GeometryNodeTransform", Translation=(0.0, 0.0, length / 2))
    stand.inputs["Rotation"].default_value = (math.pi / 2, 0.0, 0.0)
    link(grid.outputs["Mesh"], stand.inputs["Geometry"])

    # lean of each instance: the wind tilts it about the horizontal axis across the wind
    wind_pt = nodes.new("GeometryNodeInputNamedAttribute")
    wind_pt.data_type = "FLOAT_VECTOR"
    wind_pt.inputs["Name"].default_value = "wind"
    split = nodes.new("ShaderNodeSeparateXYZ")
    link(wind_pt.outputs["Attribute"], split.inputs["Vector"])
    yaw = nodes.new("FunctionNodeRandomValue")
    yaw.data_type = "FLOAT"
    _float_socket(yaw.inputs, "Min").default_value = 0.0
    _float_socket(yaw.inputs, "Max").default_value = 2 * math.pi
    euler = nodes.new("ShaderNodeCombineXYZ")
    link(math_node("MULTIPLY", split.outputs["Y"], 1.2).outputs[0], euler.inputs["X"])
    link(math_node("MULTIPLY", split.outputs["X"], -1.2).outputs[0], euler.inputs["Y"])
    link(_float_socket(yaw.outputs, "Value"), euler.inputs["Z"])
    rotation = nodes.new("FunctionNodeEulerToRotation")
    link(euler.outputs["Vector"], rotation.inputs["Euler"])
    inst = nodes.new("GeometryNodeInstanceOnPoints")
    link(store.outputs["Geometry"], inst.inputs["Points"])
    link(stand.outputs["Geometry"], inst.inputs["Instance"])
    link(rotation.outputs["Rotation"], inst.inputs["Rotation"])
    realize = nodes.new("GeometryNodeRealizeInstances")
    link(inst.outputs["Instances"], realize.inputs["Geometry"])

    # bend of the realized vertices: offset = wind * L * (z / L)^2 (z of the leaned blade)
    pos_v = nodes.new("GeometryNodeInputPosition")
    if per_vertex:  # the noise again, now at every realized vertex (position + drift)
        at_vertex = math_node("ADD", pos_v.outputs["Position"], drift.outputs["Vector"], vector=True)
        noise_v = node("ShaderNodeTexNoise", Scale=0.15, Detail=2.0)
        link(at_vertex.outputs["Vector"], noise_v.inputs["Vector"])
        wind_v = math_node("SUBTRACT", noise_v.outputs["Color"], (0.5, 0.5, 0.5), vector=True)
        wind_v = math_node("MULTIPLY", wind_v.outputs["Vector"], (1.0, 1.0, 0.0), vector=True)
        wind_out = wind_v.outputs["Vector"]
    else:
        wind_v = nodes.new("GeometryNodeInputNamedAttribute")
        wind_v.data_type = "FLOAT_VECTOR"
        wind_v.inputs["Name"].default_value = "wind"
        wind_out = wind_v.outputs["Attribute"]
    z = nodes.new("ShaderNodeSeparateXYZ")
    link(pos_v.outputs["Position"], z.inputs["Vector"])
    rel = math_node("DIVIDE", z.outputs["Z"], length)
    k = math_node("MULTIPLY", rel.outputs[0], rel.outputs[0])
    k = math_node("MULTIPLY", k.outputs[0], 0.8 * length)
    offset = nodes.new("ShaderNodeVectorMath")
    offset.operation = "SCALE"
    link(wind_out, offset.inputs[0])
    link(k.outputs[0], offset.inputs["Scale"])
    set_pos = nodes.new("GeometryNodeSetPosition")
    link(realize.outputs["Geometry"], set_pos.inputs["Geometry"])
    link(offset.outputs["Vector"], set_pos.inputs["Offset"])
    link(set_pos.outputs["Geometry"], out.inputs[0])
    return tree


def _float_socket(sockets, name: str):
    """The float socket called ``name``: Random Value's float 'Min' was the socket 'Min_001' beside
    a vector 'Min' up to Blender 4.5; from 5.2 it has the one socket of its data type, 'Min'."""
    return next(s for s in sockets if s.name == name and s.type == "VALUE")


def bench_geometry_nodes(plan: dict[str, Any], frames: int, per_vertex: bool = False) -> dict[str, Any]:
    scene = _fresh_scene()
    obj = _ground_plane("PeerGN", plan)
    mod = obj.modifiers.new("GrassWind", "NODES")
    mod.node_group = build_geometry_nodes_tree(plan, per_vertex=per_vertex)
    result = _time_frames(scene, frames, _evaluated_vertex_count(obj))
    result["motion_m"] = _motion(scene, frames, _mesh_sample([obj]))
    expected = plan["blades"] * 2 * (plan["segments"] + 1)
    if result["evaluated_vertices"] != expected:
        raise RuntimeError(f"GN peer evaluated {result['evaluated_vertices']} vertices, expected {expected}")
    return result


# --------------------------------------------------------------------------------------------
# Peer (c): hair particles with hair dynamics and a Wind force field


def bench_hair_dynamics(plan: dict[str, Any], frames: int) -> dict[str, Any]:
    import bpy

    scene = _fresh_scene()
    obj = _ground_plane("PeerHair", plan)
    obj.modifiers.new("Hair", "PARTICLE_SYSTEM")
    psys = obj.particle_systems[0]
    settings = psys.settings
    settings.type = "HAIR"
    settings.count = plan["blades"]
    settings.hair_length = plan["length"]
    settings.hair_step = plan["segments"]
    settings.emit_from = "FACE"
    settings.distribution = "RAND"
    settings.child_type = "NONE"
    psys.use_hair_dynamics = True  # cloth solver with default quality / stiffness
    cache = psys.point_cache
    cache.frame_start = 1
    cache.frame_end = frames + 10  # covers the timed frames and the two motion frames

    # Wind force field blowing along the field's wind direction (a wind field pushes along its +Z)
    d = math.radians(plan["wind_direction_deg"])
    bpy.ops.object.effector_add(type="WIND", location=(0.0, 0.0, plan["length"]))
    wind = bpy.context.object
    wind.rotation_euler = (0.0, math.pi / 2, d)
    wind.field.strength = plan["wind_speed"]
    wind.field.noise = 1.0  # some turbulence, like ours and the GN noise

    def check() -> int:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        return len(obj.evaluated_get(depsgraph).particle_systems[0].particles)

    def tips():  # evaluated tip keys of some strands (world space)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        ev = obj.evaluated_get(depsgraph)
        ps, mod = ev.particle_systems[0], ev.modifiers[0]
        step = max(1, len(ps.particles) // 64)
        return [tuple(ps.particles[i].hair_keys[-1].co_object(ev, mod, ps.particles[i]))
                for i in range(0, len(ps.particles), step)]

    result = _time_frames(scene, frames, check)
    result["motion_m"] = _motion(scene, frames, tips)
    cloth = psys.cloth.settings
    result["cloth"] = {"quality": cloth.quality, "mass": cloth.mass,
                       "bending_stiffness": cloth.bending_stiffness, "air_damping": cloth.air_damping}
    if result["evaluated_vertices"] != plan["blades"]:
        raise RuntimeError(f"hair peer evaluated {result['evaluated_vertices']} strands, "
                           f"expected {plan['blades']}")
    result["strands"] = result.pop("evaluated_vertices")
    return result


# --------------------------------------------------------------------------------------------
# Peer (a): ours, through the add-on


def bench_ours(plan: dict[str, Any], frames: int, strips_only: bool = False) -> dict[str, Any]:
    """Our field through the add-on: ``field_add`` with the plan's blocks, LOD off, rebuilt.
    ``strips_only``: its species table emptied (one plain grass: no flowers, no leaves at the
    stems' foot, so no Geometry Nodes instances), what the Geometry Nodes peers draw."""
    import bpy
    scene = _fresh_scene()
    common.load(addon=True)
    result = bpy.ops.windgrass.field_add(blocks_x=plan["blocks_x"], blocks_y=plan["blocks_y"])
    if "FINISHED" not in result:
        raise RuntimeError(f"windgrass.field_add returned {result}")
    item = scene.windgrass.fields[scene.windgrass.active_index]
    item.lod.enabled = False  # every blade drawn as geometry (no cards, no ground texture LOD)
    if strips_only:
        item.blade.species.clear()
    scene.render.fps = item.render.fps
    scene.frame_start = item.render.frame_start
    result = bpy.ops.windgrass.field_rebuild()  # fresh runtime: frame 1 below runs the preroll
    if "FINISHED" not in result:
        raise RuntimeError(f"windgrass.field_rebuild returned {result}")
    coll = item.collection
    blades = [o for o in coll.all_objects if o.type == "MESH" and o.get("wg_role") == "blades"]
    cards = [o for o in coll.all_objects if o.get("wg_role") == "cards"]
    if not blades:
        raise RuntimeError("the field's collection has no blade objects")

    def check() -> int:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        return sum(len(o.evaluated_get(depsgraph).data.vertices) for o in blades)

    result = _time_frames(scene, frames, check)
    result["motion_m"] = _motion(scene, frames, _mesh_sample(blades))
    expected = plan["blades"] * 2 * (plan["segments"] + 1)
    if result["evaluated_vertices"] != expected:
        raise RuntimeError(f"our field evaluated {result['evaluated_vertices']} blade vertices, "
                           f"expected {expected}")
    result["blade_objects"] = len(blades)
    result["card_objects"] = len(cards)
    return result


# --------------------------------------------------------------------------------------------


def _safe(fn: Callable[..., dict[str, Any]], *args: Any) -> dict[str, Any]:
    try:
        return fn(*args)
    except Exception as exc:  # a peer that fails reports why, the others still run
        return {"error": f"{type(exc).__name__}: {exc}"}


PEERS = ("ours", "ours_strips", "geometry_nodes", "geometry_nodes_vertex_noise", "hair_dynamics")
GOALS = {"ratio_ours_to_gn": 1 / 20, "ratio_ours_to_hair": 1 / 200}
RATIOS = (("geometry_nodes", "ratio_ours_to_gn"), ("ours_strips", "ratio_ours_to_ours_strips"),
          ("geometry_nodes_vertex_noise", "ratio_ours_to_gn_vertex_noise"),
          ("hair_dynamics", "ratio_ours_to_hair"))


def _run_peer(name: str, plan: dict[str, Any], frames: int) -> dict[str, Any]:
    if name == "ours":
        return bench_ours(plan, frames)
    if name == "ours_strips":
        return bench_ours(plan, frames, strips_only=True)
    if name == "geometry_nodes":
        return bench_geometry_nodes(plan, frames)
    if name == "geometry_nodes_vertex_noise":
        return bench_geometry_nodes(plan, frames, per_vertex=True)
    if name == "hair_dynamics":
        return bench_hair_dynamics(plan, frames)
    raise ValueError(f"unknown peer {name!r}; one of {', '.join(PEERS)}")


def run_peers(blade_counts=(10_000, 100_000), frames: int = 3, ours: bool = True,
              peers: tuple[str, ...] = PEERS) -> dict[str, Any]:
    """Time every peer at every blade count; ms per frame (median of ``frames`` timed frames).

    Returns {"blades": real counts, "frames", "results": {"<requested count>": {"<peer>_ms",
    "ratio_ours_to_gn", "ratio_ours_to_gn_vertex_noise", "ratio_ours_to_hair", "detail"}},
    "blender", "notes", ...}. A peer that fails gives None and "<peer>_error"; it never raises.
    """
    _prepare_blender_env()
    import bpy

    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    unknown = [p for p in peers if p not in PEERS]
    if unknown:
        raise ValueError(f"unknown peers {unknown}; valid: {', '.join(PEERS)}")
    t_start = time.perf_counter()
    results: dict[str, Any] = {}
    actual = []
    for n in blade_counts:
        plan = field_plan(n)
        actual.append(plan["blades"])
        detail: dict[str, Any] = {"plan": plan}
        for name in peers:
            if name == "ours" and not ours:
                continue
            t0 = time.perf_counter()
            detail[name] = _safe(_run_peer, name, plan, frames)
            detail[name]["total_s"] = round(time.perf_counter() - t0, 2)
        row: dict[str, Any] = {}
        for name in PEERS:
            r = detail.get(name)
            row[f"{name}_ms"] = round(r["median_ms"], 2) if r and "median_ms" in r else None
            if r and "error" in r:
                row[f"{name}_error"] = r["error"]
        for peer, key in RATIOS:
            a, b = row["ours_ms"], row[f"{peer}_ms"]
            row[key] = round(a / b, 5) if a is not None and b else None
        strips, gn = row.get("ours_strips_ms"), row.get("geometry_nodes_ms")
        row["ratio_ours_strips_to_gn"] = round(strips / gn, 5) if strips is not None and gn else None
        for key, goal in GOALS.items():  # goals: ours <= 1/20 of GN, <= 1/200 of hair dynamics
            row[key.replace("ratio_ours_to", "meets_goal")] = None if row[key] is None else row[key] <= goal
        row["detail"] = detail
        results[str(n)] = row
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return {
        "blades": actual,
        "frames": frames,
        "results": results,
        "blender": bpy.app.version_string,
        "goal": dict(GOALS),
        "total_s": round(time.perf_counter() - t_start, 1),
        "cpu_count": os.cpu_count(),
        "notes": NOTES,
    }


NOTES = (
    "ms per scene.frame_set (depsgraph evaluation included, evaluated mesh read back), median of the "
    "timed frames 2..frames+1 after an untimed warm-up at frame 1; each peer in a fresh empty scene; "
    "the same blade count (a multiple of our 512-blade block), area, blade length/width and 5 segments "
    "for all. ours: add-on field, LOD off (every blade a 12-vertex strip). geometry_nodes: Points (exact "
    "count) -> instance 12-vertex strip, lean + bend by a Noise Texture sampled once per blade at root + "
    "wind drift * Scene Time -> Realize Instances (the cheapest sound GN wind, the strongest peer). "
    "geometry_nodes_vertex_noise: the same, but the bend samples the noise again at every realized "
    "vertex (the common tutorial recipe). hair_dynamics: HAIR particles, hair_step 5, "
    "use_hair_dynamics with default cloth settings, Wind force field; frames stepped forward from the "
    "cache start. Results key = requested count; 'blades' lists the real counts. Wall-clock timings "
    "on a shared machine: compare ratios from one run."
)


def main(argv: list[str] | None = None) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--blades", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--frames", type=int, default=3, help="timed frames per peer (default 3)")
    parser.add_argument("--no-ours", action="store_true", help="skip our field (peers only)")
    parser.add_argument("--peers", nargs="+", default=list(PEERS), choices=PEERS)
    args = parser.parse_args(argv)
    # Blender's C code prints to file descriptor 1; keep stdout for the one JSON object.
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        out = run_peers(tuple(args.blades), frames=args.frames, ours=not args.no_ours,
                        peers=tuple(args.peers))
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
    common.emit(out, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
