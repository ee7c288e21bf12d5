"""Handover benchmark: blade strips written whole against strips a Geometry Nodes modifier builds.

    python headless/bench_handover.py [--blades 10000 100000] [--frames N] [--json]

prints one JSON object (``python3.11 dev.py bench --handover``). Issue #60 asks whether the blade
strips should be built by Geometry Nodes from each blade's joints, handing Blender at most 64 bytes
per blade per frame instead of the strip's 12 vertices (144 bytes), and to keep the faster way.
Each way here draws the same frames of the same field (the engine's blade strips of the Add-menu
settings, every blade as geometry, ``bench_peers.field_plan``'s blocks), worked out before the
timing, so only the handover and Blender's evaluation are timed, the way the add-on times a frame:
a ``frame_change_pre`` handler writes the frame, then ``scene.frame_set`` evaluates the depsgraph
(``bench_peers._time_frames``: the median, split into the handler and the evaluation).

* ``strips``: today's way (``bridge/pools.write_positions``): the strip's two vertices per joint,
  (segments + 1) x 2 x 12 bytes, into a mesh of quads; Blender draws it as it is.
* ``gn_extrude``: the joints, (segments + 1) x 12 bytes, and the side's turn about the vertical at
  each joint (the blade's facing plus the twist Phi_j, paper V.A), 4 bytes each, into a mesh of the
  joints and the segments' edges; the widths are written once. A Geometry Nodes modifier makes each
  joint's side ``(-sin a, cos a, 0) * width``, moves the joint half a side to the left, extrudes the
  edges into quads and moves the copies a side to the right: the same strips, made each frame.
* ``gn_sample``: the same 16 bytes per joint into a mesh of joints alone; the strips keep a mesh of
  their own (quads, UVs, the colours written once), and a modifier places each of its vertices
  from its joint (Sample Index): position = joint + (-sin a, cos a, 0) * its signed half width.

The cards (``--cards-m``: a field that wide from ``bench_scale.py``'s camera, the LOD on), two ways:

* ``cards``: today's: each card's 4 corners (48 bytes) and its opacity per corner, the UV map
  ``wg_fade`` (32 bytes), every frame;
* ``cards_gn``: a point per card, the middle of its top edge, the edge's turn and the opacity
  (20 bytes); the cards keep a mesh of their own whose bottom corners never move, and a modifier
  places the top corners from the card's point and stores the opacity as ``wg_fade``.

Each way's evaluated mesh is checked against the engine's vertices (``max_error_m``; the cards'
opacity too). "ratio" is a way's frame against ``strips`` (``cards``) in the same run.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # (Blender's -P does not put the script's folder on the path)
import bench_peers  # noqa: E402
import common  # noqa: E402
import numpy as np  # noqa: E402

WAYS = ("strips", "gn_extrude", "gn_sample")
CARD_WAYS = ("cards", "cards_gn")


def engine_frames(plan: dict[str, Any], frames: int) -> dict[str, Any]:
    """The blade strips of frames 1 .. frames + 1 (every block, LOD off) as (blades, 2 (n + 1), 3)
    float32 arrays, with one block's faces and the engine's time per frame."""
    common.load()
    from windgrass.grass_addon import kinematics, schema
    from windgrass.grass_addon.field import GrassField

    params = schema.defaults().replace({"field.blocks_x": plan["blocks_x"], "field.blocks_y": plan["blocks_y"],
                                        "lod.enabled": False})
    field = GrassField(params)
    n = params.blade.segments
    out, times = [], []
    for f in range(1, frames + 2):
        t0 = time.perf_counter()
        part = field.frame(f).blades
        times.append(time.perf_counter() - t0)
        verts = part.vertices[:part.count * part.shape.verts_per_object // part.shape.k]
        out.append(np.ascontiguousarray(verts.reshape(-1, 2 * (n + 1), 3)))
    blocks = out[0].shape[0] // field.layout.blades_per_block
    faces = kinematics.blade_faces(field.layout)
    step = field.layout.blades_per_block * 2 * (n + 1)
    all_faces = (faces[None] + (np.arange(blocks, dtype=np.int32) * step)[:, None, None]).reshape(-1, 4)
    return {"strips": out, "faces": all_faces, "segments": n,
            "engine_ms": round(1e3 * statistics.median(times[1:]), 2)}


def _joints(strip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(joints (blades, n + 1, 3), sides (blades, n + 1, 3)): the strip's centre line and its
    left-to-right vector at each joint."""
    left, right = strip[:, 0::2], strip[:, 1::2]
    return 0.5 * (left + right), right - left


class _Tree:
    """A Geometry Nodes tree being built: nodes by type, links, named attributes, math."""

    def __init__(self, name: str):
        import bpy

        self.tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
        self.tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        self.tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        self.source = self.node("NodeGroupInput").outputs[0]
        self.sink = self.node("NodeGroupOutput").inputs[0]

    def node(self, kind: str):
        return self.tree.nodes.new(kind)

    def link(self, a, b) -> None:
        self.tree.links.new(a, b)

    def named(self, name: str, kind: str):
        node = self.node("GeometryNodeInputNamedAttribute")
        node.data_type = kind
        node.inputs["Name"].default_value = name
        return node.outputs["Attribute"]

    def math(self, operation: str, a, b=None):
        node = self.node("ShaderNodeMath")
        node.operation = operation
        self.link(a, node.inputs[0])
        if b is not None:
            node.inputs[1].default_value = b
        return node.outputs[0]

    def scale(self, vector, by):
        node = self.node("ShaderNodeVectorMath")
        node.operation = "SCALE"
        self.link(vector, node.inputs[0])
        if isinstance(by, float):
            node.inputs["Scale"].default_value = by
        else:
            self.link(by, node.inputs["Scale"])
        return node.outputs["Vector"]

    def across(self, angle):
        """The unit vector across the blade at a turn ``angle``: (-sin a, cos a, 0)."""
        side = self.node("ShaderNodeCombineXYZ")
        self.link(self.math("MULTIPLY", self.math("SINE", angle), -1.0), side.inputs["X"])
        self.link(self.math("COSINE", angle), side.inputs["Y"])
        return side.outputs["Vector"]

    def sampler(self, source_object, index_name: str):
        """``sample(kind, value)``: ``value`` read on ``source_object``'s point whose index each
        point of this geometry holds in ``index_name`` (Object Info, Sample Index)."""
        info = self.node("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = source_object
        index = self.named(index_name, "INT")

        def sample(kind: str, value):
            node = self.node("GeometryNodeSampleIndex")
            node.data_type = kind
            node.domain = "POINT"
            self.link(info.outputs["Geometry"], node.inputs["Geometry"])
            self.link(value, node.inputs["Value"])
            self.link(index, node.inputs["Index"])
            return node.outputs["Value"]

        return sample

    def placed(self, sample, across, selection=None):
        """The input geometry with its points (those of ``selection``) at their source point's
        position + (-sin a, cos a, 0) * ``across``, a = the source point's ``wg_turn``."""
        place = self.node("ShaderNodeVectorMath")
        place.operation = "ADD"
        self.link(sample("FLOAT_VECTOR", self.node("GeometryNodeInputPosition").outputs["Position"]), place.inputs[0])
        self.link(self.scale(self.across(sample("FLOAT", self.named("wg_turn", "FLOAT"))), across), place.inputs[1])
        move = self.node("GeometryNodeSetPosition")
        self.link(self.source, move.inputs["Geometry"])
        if selection is not None:
            self.link(selection, move.inputs["Selection"])
        self.link(place.outputs["Vector"], move.inputs["Position"])
        return move.outputs["Geometry"]


def _extrude_tree():
    """Joints (a vertex each, an edge per segment; ``wg_turn``, ``wg_width``) -> the blade strips:
    side = ``(-sin wg_turn, cos wg_turn, 0) * wg_width``; every joint moved by -side / 2, the
    edges extruded into quads, the copies (the right-hand vertices) moved by side."""
    t = _Tree("HandoverExtrude")
    side = t.scale(t.across(t.named("wg_turn", "FLOAT")), t.named("wg_width", "FLOAT"))
    move = t.node("GeometryNodeSetPosition")
    t.link(t.source, move.inputs["Geometry"])
    t.link(t.scale(side, -0.5), move.inputs["Offset"])
    extrude = t.node("GeometryNodeExtrudeMesh")  # (its Offset would be read per edge: averaged)
    extrude.mode = "EDGES"
    extrude.inputs["Offset Scale"].default_value = 0.0
    t.link(move.outputs["Geometry"], extrude.inputs["Mesh"])
    right = t.node("GeometryNodeSetPosition")  # the copies carry the joints' attributes
    t.link(extrude.outputs["Mesh"], right.inputs["Geometry"])
    t.link(extrude.outputs["Top"], right.inputs["Selection"])
    t.link(side, right.inputs["Offset"])
    t.link(right.outputs["Geometry"], t.sink)
    return t.tree


def _sample_tree(joints_object):
    """The strips' own mesh (its quads, UVs and colours kept; ``wg_joint``: each vertex's joint,
    ``wg_across``: its signed half width) placed each frame from ``joints_object`` (a vertex per
    joint, ``wg_turn``): position = joint + (-sin turn, cos turn, 0) * across."""
    t = _Tree("HandoverSample")
    t.link(t.placed(t.sampler(joints_object, "wg_joint"), t.named("wg_across", "FLOAT")), t.sink)
    return t.tree


def _joint_mesh(blades: int, n: int):
    """A mesh of ``blades`` chains of n + 1 vertices (joints) and n edges."""
    import bpy

    mesh = bpy.data.meshes.new("HandoverJoints")
    joints = blades * (n + 1)
    mesh.vertices.add(joints)
    start = (np.arange(blades, dtype=np.int32) * (n + 1))[:, None] + np.arange(n, dtype=np.int32)[None, :]
    edges = np.stack([start, start + 1], axis=-1).reshape(-1, 2)
    mesh.edges.add(len(edges))
    mesh.edges.foreach_set("vertices", edges.ravel())
    mesh.update()
    return mesh


def _timed(scene, obj, write, frames: int) -> tuple[dict[str, Any], Any, np.ndarray]:
    """``bench_peers._time_frames`` with ``write`` as a ``frame_change_pre`` handler, then frame
    ``frames + 1``: (the timing, ``obj``'s evaluated mesh there, its positions as (vertices, 3))."""
    import bpy

    def check() -> int:
        return len(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices)

    bpy.app.handlers.frame_change_pre.append(write)
    try:
        result = bench_peers._time_frames(scene, frames, check)
        scene.frame_set(frames + 1)
    finally:
        bpy.app.handlers.frame_change_pre.remove(write)
    drawn = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    flat = np.zeros(len(drawn.vertices) * 3, np.float32)
    drawn.attributes["position"].data.foreach_get("vector", flat)
    return result, drawn, flat.reshape(-1, 3)


def run_way(way: str, data: dict[str, Any], frames: int) -> dict[str, Any]:
    """One way's frames in a fresh scene: the median frame, its split, the bytes handed over per
    blade per frame and the largest distance between Blender's evaluated vertices and the engine's."""
    import bpy
    from windgrass.grass_addon.bridge import meshes, pools

    scene = bench_peers._fresh_scene()
    strips: list[np.ndarray] = data["strips"]
    n = data["segments"]
    blades = strips[0].shape[0]
    corners = np.zeros((len(data["faces"]) * 4, 2), np.float32)
    joints, sides = zip(*(_joints(strip) for strip in strips))
    turns = [np.arctan2(-side[..., 0], side[..., 1]).astype(np.float32).ravel() for side in sides]
    widths = np.linalg.norm(sides[0], axis=-1).astype(np.float32)  # (the engine's widths never change)
    if way == "strips":
        mesh = target = meshes.quad_mesh("HandoverStrips", blades * 2 * (n + 1), data["faces"], corners, None, {})
        handed = [(strip.reshape(-1, 3), None) for strip in strips]
    else:
        mesh = _joint_mesh(blades, n)
        handed = [(joint.reshape(-1, 3), turn) for joint, turn in zip(joints, turns)]
        if way == "gn_extrude":
            pools.write_point_values(mesh, "wg_width", widths.ravel())
            target = mesh
        else:  # the strips' mesh: its own quads, each vertex told its joint and signed half width
            target = meshes.quad_mesh("HandoverStrips", blades * 2 * (n + 1), data["faces"], corners, None, {})
            pools.write_point_values(target, "wg_joint", np.repeat(np.arange(blades * (n + 1)), 2), "INT")
            pools.write_point_values(target, "wg_across", (widths[..., None] * [-0.5, 0.5]).ravel())
    joints_object = bpy.data.objects.new("HandoverJoints", mesh)
    obj = joints_object if target is mesh else bpy.data.objects.new("Handover", target)
    for each in {joints_object, obj}:
        scene.collection.objects.link(each)
    if way != "strips":
        modifier = obj.modifiers.new("Strips", "NODES")
        modifier.node_group = _extrude_tree() if way == "gn_extrude" else _sample_tree(joints_object)
    if obj is not joints_object:
        joints_object.hide_render = joints_object.hide_viewport = True

    def write(scene_, *_args) -> None:
        positions, turn = handed[min(scene_.frame_current, len(handed)) - 1]
        pools.write_positions(mesh, positions)
        if turn is not None:
            pools.write_point_values(mesh, "wg_turn", turn)
        mesh.update()

    result, _drawn, got = _timed(scene, obj, write, frames)
    strip = strips[frames]
    if way == "gn_extrude":  # the joints moved left, then their copies on the right
        want = np.concatenate([strip[:, 0::2].reshape(-1, 3), strip[:, 1::2].reshape(-1, 3)])
    else:
        want = strip.reshape(-1, 3)
    error = float(np.abs(got - want).max()) if got.shape == want.shape else math.inf
    bytes_per_blade = 2 * (n + 1) * 12 if way == "strips" else (n + 1) * 16
    result.update(bytes_per_blade=bytes_per_blade, max_error_m=error, blades=blades)
    return result


def engine_cards(size_m: float, frames: int) -> dict[str, Any]:
    """The cards of frames 1 .. frames + 1 of a ``size_m`` field seen from ``bench_scale.py``'s
    camera (the LOD on: the cards the add-on draws): their corners (cards, 4, 3) and opacity per
    corner (cards, 4), with their quads."""
    common.load()
    import bench_scale
    from windgrass.grass_addon import kinematics, roles
    from windgrass.grass_addon.field import GrassField

    params = bench_scale._params(size_m)
    camera = bench_scale._camera(params)
    field = GrassField(params)
    corners, fades = [], []
    for f in range(1, frames + 2):
        part = field.frame(f, 0.0, camera).cards
        local = part.local[:part.count]
        if f == 1:
            fixed = local.copy()  # (the same blocks every frame: the camera stands still)
        assert np.array_equal(local, fixed), "the cards' blocks moved"
        cards = part.count * field.layout.cells_per_block_total
        corners.append(np.ascontiguousarray(part.vertices[:cards * 4].reshape(cards, 4, 3)))
        fades.append(roles.card_fade(field.layout, local, part.lod)[roles.FADE].reshape(cards, 4, 2)[..., 0].copy())
    faces = kinematics.card_faces(field.layout)
    per_block = field.layout.cells_per_block_total * 4
    blocks = len(fixed)
    quads = (faces[None] + (np.arange(blocks, dtype=np.int32) * per_block)[:, None, None]).reshape(-1, 4)
    return {"corners": corners, "fades": fades, "faces": quads}


def _cards_tree(tops_object):
    """The cards' own mesh (bottom corners where the engine put them; ``wg_card``: each vertex's
    card, ``wg_across``: 0 at the bottom, + or - half the card's width at its top) with its top
    corners placed each frame from ``tops_object`` (a vertex per card on its top edge's middle,
    ``wg_turn``: the top edge's direction less 90 degrees, ``wg_fade``: its opacity), and each
    corner's opacity stored as the UV map ``wg_fade`` the cards' material reads."""
    t = _Tree("HandoverCards")
    sample = t.sampler(tops_object, "wg_card")
    across = t.named("wg_across", "FLOAT")
    moved = t.placed(sample, across, t.math("GREATER_THAN", t.math("ABSOLUTE", across), 0.0))  # (the top)
    fade = sample("FLOAT", t.named("wg_fade", "FLOAT"))
    pair = t.node("ShaderNodeCombineXYZ")
    t.link(fade, pair.inputs["X"])
    t.link(fade, pair.inputs["Y"])
    store = t.node("GeometryNodeStoreNamedAttribute")
    store.data_type = "FLOAT2"
    store.domain = "CORNER"
    store.inputs["Name"].default_value = "wg_fade"
    t.link(moved, store.inputs["Geometry"])
    t.link(pair.outputs["Vector"], next(i for i in store.inputs if i.name == "Value" and i.enabled))
    t.link(store.outputs["Geometry"], t.sink)
    return t.tree


def run_cards_way(way: str, data: dict[str, Any], frames: int) -> dict[str, Any]:
    """``cards`` (today: the corners and the opacity per corner, the UV map ``wg_fade``) or
    ``cards_gn`` (a point per card: its top's middle, turn and opacity), timed as ``run_way``; the
    largest distance from the engine's corners and the largest opacity error."""
    import bpy
    from windgrass.grass_addon.bridge import meshes, pools

    scene = bench_peers._fresh_scene()
    corners, fades = data["corners"], data["fades"]
    cards = corners[0].shape[0]
    mesh = meshes.quad_mesh("HandoverCards", cards * 4, data["faces"], np.zeros((cards * 4, 2), np.float32), None,
                            {}, ("wg_fade",))
    obj = bpy.data.objects.new("HandoverCards", mesh)
    scene.collection.objects.link(obj)
    # (the corners follow the quads: corner k of card c is vertex 4 c + k, as kinematics.card_faces has them)
    if way == "cards":
        handed = [(c.reshape(-1, 3), np.repeat(f.reshape(-1, 1), 2, axis=1)) for c, f in zip(corners, fades)]
        target, bytes_per_card = mesh, 4 * 12 + 4 * 8
    else:
        pools.write_positions(mesh, corners[0].reshape(-1, 3))  # (the bottom corners never move)
        pools.write_point_values(mesh, "wg_card", np.repeat(np.arange(cards), 4), "INT")
        half = 0.5 * np.linalg.norm(corners[0][:, 2] - corners[0][:, 3], axis=1)
        pools.write_point_values(mesh, "wg_across", (half[:, None] * [0.0, 0.0, 1.0, -1.0]).ravel())
        target = bpy.data.meshes.new("HandoverTops")
        target.vertices.add(cards)
        tops = bpy.data.objects.new("HandoverTops", target)
        scene.collection.objects.link(tops)
        tops.hide_render = tops.hide_viewport = True
        handed = []
        for c, f in zip(corners, fades):
            edge = c[:, 2] - c[:, 3]
            turn = (np.arctan2(edge[:, 1], edge[:, 0]) - 0.5 * np.pi).astype(np.float32)  # (across: (cos, sin) of it)
            handed.append((0.5 * (c[:, 2] + c[:, 3]), np.stack([turn, f[:, 0]])))
        modifier = obj.modifiers.new("Cards", "NODES")
        modifier.node_group = _cards_tree(tops)
        bytes_per_card = 12 + 4 + 4

    def write(scene_, *_args) -> None:
        positions, extra = handed[min(scene_.frame_current, len(handed)) - 1]
        pools.write_positions(target, positions)
        if way == "cards":
            meshes.write_uv(target, "wg_fade", extra)
        else:
            pools.write_point_values(target, "wg_turn", extra[0])
            pools.write_point_values(target, "wg_fade", extra[1])
        target.update()

    result, drawn, got = _timed(scene, obj, write, frames)
    opacity = meshes.read_uv(drawn, "wg_fade")
    want = corners[frames].reshape(-1, 3)
    error = float(np.abs(got - want).max()) if got.shape == want.shape else math.inf
    fade_error = float(np.abs(opacity[:, 0] - fades[frames].reshape(-1)).max())
    result.update(bytes_per_card=bytes_per_card, max_error_m=error, max_fade_error=fade_error, cards=cards)
    return result


def run(blade_counts=(10_000, 100_000), frames: int = 5, cards_m: float = 102.4) -> dict[str, Any]:
    bench_peers._prepare_blender_env()
    import bpy

    out: dict[str, Any] = {"blender": bpy.app.version_string, "frames": frames, "ways": list(WAYS), "runs": []}
    for blades in blade_counts:
        plan = bench_peers.field_plan(blades)
        data = engine_frames(plan, frames)
        row: dict[str, Any] = {"blades": plan["blades"], "engine_ms": data["engine_ms"]}
        for way in WAYS:
            row[way] = run_way(way, data, frames)
        base = row["strips"]["median_ms"]
        row["ratio"] = {way: round(row[way]["median_ms"] / base, 2) for way in WAYS}
        out["runs"].append(row)
    if cards_m > 0:
        data = engine_cards(cards_m, frames)
        row = {"field_m": cards_m, **{way: run_cards_way(way, data, frames) for way in CARD_WAYS}}
        row["ratio"] = round(row["cards_gn"]["median_ms"] / row["cards"]["median_ms"], 2)
        out["cards"] = row
    return out


def main(argv: list[str] | None = None) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--blades", nargs="+", type=int, default=[10_000, 100_000])
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--cards-m", type=float, default=102.4,
                        help="the cards of a field this wide, from bench_scale.py's camera (0: none)")
    args = parser.parse_args(argv)
    common.emit(run(tuple(args.blades), args.frames, args.cards_m), args)
    return 0


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    common.finish(main(argv))
