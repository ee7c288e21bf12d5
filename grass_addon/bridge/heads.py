"""Flowers, leaves and the artist's own plants in Blender: a Geometry Nodes modifier on the blade slots.

The engine marks each stem that carries something on its first vertex (``heads.tip_marks``: the
point attributes ``wg_head``: the species + 1, the size in metres, a turn about the stem,
``wg_stem``: the vertex's index, and ``wg_leaf``: its leaves' length); the field's node group
``Windgrass Heads`` (``fill_group``) makes a point per stem, puts that species' head on the stem's
tip, turned to its last segment, its leaves (``grass_addon/tufts.py``) on its root, turned to its
first, or bends the species' own plant along the stem, and joins them to the strips. Blender
builds them, on its threads, from the positions the engine wrote: nothing more is handed over per
frame. A species' source is a
Windgrass flower (``grass_addon/heads.py``: an object in no scene, coloured per vertex,
``wg_color``) or the artist's own collection (the species column ``plant``).

Made and changed only inside ``lifecycle`` (operators, edits, file load: ``scene.build_slots``
makes them with the slots); a colour edit rewrites the head meshes' colours in place.
"""

from __future__ import annotations

import bpy
import numpy as np

from .. import heads as shapes
from .. import plants as engine_plants
from .. import tufts
from ..schema import Params
from . import materials, meshes, owned
from .registry import warn_once

ATTR_HEAD = "wg_head"  # point vector of the blade slots: (species + 1, size m, turn rad) of a stem
ATTR_STEM = "wg_stem"  # point float of the blade slots: the stem's first vertex (a colour attribute
# of four read back from an Alembic cache crashed Blender 5.3: two plain attributes instead)
ATTR_LEAF = "wg_leaf"  # point float of the blade slots: the longest leaf at a stem's foot (m; 0: none)
ATTR_CARRY = "wg_carry"  # point float of the blade slots: on vertex 0 how many stems carry something,
# on vertex k + 1 the k-th one's first vertex (the tree makes a point for each of those stems alone)
ATTR_TIP_DIR = "wg_tip_dir"  # (in the tree) the stem's last segment at its tip
ATTR_FOOT_DIR = "wg_foot_dir"  # (in the tree) the stem's first segment at its root
ATTR_SEED_BASE = "wg_seed_base"  # (in the tree) the stem's joint n - 2: where its seed head's spindle starts
ATTR_SPIKE_BASE = "wg_spike_base"  # (in the tree) the stem's joint n - 1: where a spike starts
ATTR_TIP = "wg_tip"  # (in the tree) the stem's tip
ATTR_LOCAL = "wg_local"  # (in the tree) a plant's point where it is in its source
ATTR_COLOR = "wg_color"  # point colour of a head mesh
ATTR_ROUGH = "wg_rough"  # point roughness of a head mesh
GROUP_NAME = "Windgrass Heads"
MODIFIER = "Windgrass Heads"


def _head_mesh(name: str, shape: str, colour) -> bpy.types.Mesh:
    """A Blender mesh of a Windgrass head, coloured per vertex."""
    m = shapes.head_mesh(shape)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(m.vertices.tolist(), [], m.faces)
    mesh.attributes.new(ATTR_COLOR, "FLOAT_COLOR", "POINT")
    _write_colours(mesh, m, shape, colour)
    mesh.attributes.new(ATTR_ROUGH, "FLOAT", "POINT")
    mesh.attributes[ATTR_ROUGH].data.foreach_set("value", m.roughness)
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    mesh.update()
    return mesh


def _write_colours(mesh, m, shape: str, colour) -> None:
    """``wg_color`` of a head mesh: its petals ``colour``, its shape's centre and green."""
    rgba = np.ones((len(m.vertices), 4), np.float32)
    rgba[:, :3] = shapes.colours(m, shape, colour)
    mesh.attributes[ATTR_COLOR].data.foreach_set("color", rgba.ravel())


def head_material(name: str) -> bpy.types.Material:
    """Petals lit from both sides: the head's colour (``wg_color``) and roughness (``wg_rough``),
    part of the light through (a petal is thin)."""
    mat = materials.with_nodes(bpy.data.materials.new(name))
    mat.use_backface_culling = False  # petals are seen from both sides
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    colour = nt.nodes.new("ShaderNodeAttribute")
    colour.attribute_name = ATTR_COLOR
    rough = nt.nodes.new("ShaderNodeAttribute")
    rough.attribute_name = ATTR_ROUGH
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    through = nt.nodes.new("ShaderNodeBsdfTranslucent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.3
    nt.links.new(colour.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(rough.outputs["Fac"], bsdf.inputs["Roughness"])
    nt.links.new(colour.outputs["Color"], through.inputs["Color"])
    nt.links.new(bsdf.outputs[0], mix.inputs[1])
    nt.links.new(through.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    mat.diffuse_color = (0.9, 0.8, 0.2, 1.0)
    return mat


class _Tree:
    """Nodes of a tree added and linked by short calls (positions laid out left to right)."""

    def __init__(self, tree):
        self.tree = tree
        self.column = 0

    def node(self, kind: str, **props):
        n = self.tree.nodes.new(kind)
        for key, value in props.items():
            setattr(n, key, value)
        n.location = (200 * self.column, 0)
        self.column += 1
        return n

    def link(self, out, into) -> None:
        self.tree.links.new(out, into)

    def math(self, op: str, a, b=None, vector: bool = False):
        n = self.node("ShaderNodeVectorMath" if vector else "ShaderNodeMath", operation=op)
        for i, value in enumerate((a, b)):
            if value is None:
                continue
            if isinstance(value, bpy.types.NodeSocket):
                self.link(value, n.inputs[i])
            else:
                n.inputs[i].default_value = value
        return n.outputs[0]

    def vmath(self, op: str, a, b, scale=None, out: str | None = None):
        """A vector math node's result (``out``: "Value" for lengths and dot products)."""
        n = self.node("ShaderNodeVectorMath", operation=op)
        for i, value in enumerate((a, b)):
            if value is not None:
                self.link(value, n.inputs[i])
        if scale is not None:
            if isinstance(scale, bpy.types.NodeSocket):
                self.link(scale, n.inputs["Scale"])
            else:
                n.inputs["Scale"].default_value = scale
        return n.outputs[out] if out else n.outputs["Vector"]

    def attribute(self, name: str, data_type: str):
        n = self.node("GeometryNodeInputNamedAttribute", data_type=data_type)
        n.inputs["Name"].default_value = name
        kind = {"FLOAT_VECTOR": "VECTOR", "FLOAT_COLOR": "RGBA"}.get(data_type, "VALUE")
        return _socket(n.outputs, "Attribute", kind)

    def head(self):
        """The mark: (species + 1, size, turn, first vertex) sockets (``wg_head``, ``wg_stem``)."""
        parts = self.node("ShaderNodeSeparateXYZ")
        self.link(self.attribute(ATTR_HEAD, "FLOAT_VECTOR"), parts.inputs[0])
        return parts.outputs["X"], parts.outputs["Y"], parts.outputs["Z"], self.attribute(ATTR_STEM, "FLOAT")

    def position(self):
        return self.node("GeometryNodeInputPosition").outputs[0]

    def middle(self, geometry, left):
        """The middle of vertex ``left`` and the one after it (a joint's centre)."""
        pair = self.vmath("ADD", self.sample(geometry, self.position(), left),
                          self.sample(geometry, self.position(), self.math("ADD", left, 1.0)))
        return self.vmath("SCALE", pair, None, scale=0.5)

    def any_of(self, kind, kinds: list):
        """1 where ``kind`` (a species + 1, a float) is one of ``kinds``."""
        out = None
        for k in kinds:
            hit = self.math("COMPARE", kind, float(k))
            hit.node.inputs[2].default_value = 0.25
            out = hit if out is None else self.math("MAXIMUM", out, hit)
        return out

    def store(self, geometry, name: str, data_type: str, value):
        """``geometry`` with the point attribute ``name`` set to ``value`` (a socket)."""
        n = self.node("GeometryNodeStoreNamedAttribute", data_type=data_type, domain="POINT")
        n.inputs["Name"].default_value = name
        self.link(geometry, n.inputs["Geometry"])
        self.link(value, _socket(n.inputs, "Value", "VECTOR" if data_type == "FLOAT_VECTOR" else "VALUE"))
        return n.outputs[0]

    def sample(self, geometry, value, index, data_type: str = "FLOAT_VECTOR"):
        """The ``value`` of point ``index`` (a socket: a field; a number: a single value): a
        position, or a float (``data_type`` FLOAT)."""
        kind = "VECTOR" if data_type == "FLOAT_VECTOR" else "VALUE"
        n = self.node("GeometryNodeSampleIndex", data_type=data_type, domain="POINT")
        self.link(geometry, n.inputs["Geometry"])
        self.link(value, _socket(n.inputs, "Value", kind))
        if isinstance(index, bpy.types.NodeSocket):
            self.link(index, n.inputs["Index"])
        else:
            n.inputs["Index"].default_value = int(index)
        return _socket(n.outputs, "Value", kind)


def _socket(sockets, name: str, kind: str):
    """The socket ``name`` of type ``kind`` (older Blenders keep one per data type, some hidden)."""
    found = [s for s in sockets if s.name == name and s.type == kind]
    return found[0] if found else sockets[name]


HEAD, PLANT, SEED, SEED_SPAN = "head", "plant", "seed", "seed span"  # how a species' source is drawn: on
# the tips, bent along the stems, or over their top two segments (a seed head as wide as the spindle, or
# scaled evenly by the span: shapes.SPAN_SCALED)


def build_group(name: str, sources: list, segments: int, leaves: list | None = None
                ) -> bpy.types.GeometryNodeTree:
    """The node group drawing, for each species k with ``sources[k]`` = (``HEAD`` or ``PLANT``,
    an Object or a Collection) (None: nothing), that source on the stems whose ``wg_head`` species
    is k + 1, and ``leaves[k]`` (an Object, None: none) at their foot (see ``fill_group``);
    ``segments``: the stems' n."""
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    fill_group(tree, sources, segments, leaves)
    return tree


def fill_group(tree, sources: list, segments: int, leaves: list | None = None) -> None:
    """(Re)make ``tree``'s nodes. The strips come in as the engine wrote them: blade b's joint j
    at vertices 2 (n + 1) b + 2 j (left) and + 1 (right); a stem that carries something has
    ``wg_head`` (species + 1, size, turn, its first vertex) on its first vertex (a plant's on all
    of them: ``heads.tip_marks``). A point per stem that carries something (the field lists them:
    ``wg_carry``, ``carriers``; the tree holds for any density, so a density edit keeps it) reads
    it there, so the fields below are evaluated once per such stem, never per vertex (a pass over
    the strip's vertices, Mesh to Points, cost 9 ms a frame on the Add-menu field; a point for
    every stem, then those that carry nothing deleted, about 1 ms of 20 at 100 m). A ``HEAD`` is
    put on the stem's tip (the middle of its two vertices), its +Z along the last segment,
    turned about it, ``size`` wide (a stem marked for its leaves alone has size 0: no head);
    ``leaves[k]`` stands on the root, its +Z along the first segment, turned about it,
    ``wg_leaf`` long; a ``PLANT`` stands on the stem's root and is bent along it
    (``_bend_along``) and the stem's own strip is collapsed onto its root. Stems collapsed by
    the LOD (eq 9) have no segment: nothing is drawn there."""
    tree.nodes.clear()
    t = _Tree(tree)
    group_in, group_out = t.node("NodeGroupInput"), t.node("NodeGroupOutput")
    mesh = group_in.outputs[0]
    n = int(segments)
    kind, _size, _turn, first = t.head()  # (per vertex: the plants' strips)
    leaves = list(leaves or [])
    seeded = any(src is not None and src[0] in (SEED, SEED_SPAN) for src in sources) and n >= 2
    placed = _stem_points(t, mesh, n, any(leaf is not None for leaf in leaves), seeded)
    grown = t.math("GREATER_THAN", t.vmath("LENGTH", t.attribute(ATTR_TIP_DIR, "FLOAT_VECTOR"), None, out="Value"),
                   1e-6)
    carries = t.math("GREATER_THAN", t.head()[0], 0.5)
    roots = t.node("GeometryNodeDeleteGeometry", domain="POINT")
    t.link(placed, roots.inputs["Geometry"])
    t.link(t.math("LESS_THAN", t.math("MULTIPLY", grown, carries), 0.5), roots.inputs["Selection"])
    radius = t.node("GeometryNodeSetPointRadius")
    t.link(roots.outputs[0], radius.inputs["Points"])
    t.link(t.head()[1], radius.inputs["Radius"])
    heads = t.node("GeometryNodeSetPosition")  # the heads on the tips
    t.link(radius.outputs[0], heads.inputs["Geometry"])
    t.link(t.attribute(ATTR_TIP, "FLOAT_VECTOR"), heads.inputs["Position"])
    plants = [k + 1 for k, s in enumerate(sources) if s is not None and s[0] == PLANT]
    strips = mesh
    if plants:  # the plants' own strips collapse onto their roots (their joints still bend the plant)
        collapse = t.node("GeometryNodeSetPosition")
        t.link(mesh, collapse.inputs["Geometry"])
        t.link(t.any_of(kind, plants), collapse.inputs["Selection"])
        t.link(t.middle(mesh, first), collapse.inputs["Position"])  # (first: per vertex, its stem's)
        strips = collapse.outputs[0]
    join = t.node("GeometryNodeJoinGeometry")
    if any(leaf is not None for leaf in leaves):
        t.link(_leaves(t, roots.outputs[0], leaves), join.inputs[0])
    for k, source in reversed(list(enumerate(sources))):
        if source is None:
            continue
        mode, data = source
        if mode == PLANT:
            t.link(_bend_along(t, mesh, roots.outputs[0], k + 1, data, n), join.inputs[0])
        elif mode in (SEED, SEED_SPAN):
            t.link(_seed_heads(t, roots.outputs[0], k + 1, data, mode == SEED_SPAN), join.inputs[0])
        else:
            t.link(_instances(t, heads.outputs[0], k + 1, data), join.inputs[0])
    t.link(strips, join.inputs[0])  # (linked last: joined first, so the strips' vertices keep their ids)
    t.link(join.outputs[0], group_out.inputs[0])


def _stem_points(t: _Tree, mesh, n: int, leafy: bool, seeded: bool = False):
    """A point per stem of the slot object that carries something (a Points node over the
    field's list, ``wg_carry``: no pass over the strip's vertices) on its root, with its mark read
    from the stem's first vertex (``wg_head``, ``wg_stem``), its tip and last segment (``wg_tip``,
    ``wg_tip_dir``), where some species has ``leafy`` feet its leaves' length and first segment
    (``wg_leaf``, ``wg_foot_dir``), and where some has its seed heads as meshes (``seeded``) its
    joint n - 2 (``wg_seed_base``)."""
    carry = t.attribute(ATTR_CARRY, "FLOAT")  # (vertex 0: how many; vertex k + 1: the k-th one's first vertex)
    stem = t.node("GeometryNodePoints")  # only the stems that carry something (one in seven on the meadow)
    t.link(t.sample(mesh, carry, 0, "FLOAT"), stem.inputs["Count"])
    index = t.node("GeometryNodeInputIndex").outputs[0]
    base = t.sample(mesh, carry, t.math("ADD", index, 1.0), "FLOAT")
    mark = t.node("GeometryNodeSampleIndex", data_type="FLOAT_VECTOR", domain="POINT")
    t.link(mesh, mark.inputs["Geometry"])
    t.link(t.attribute(ATTR_HEAD, "FLOAT_VECTOR"), _socket(mark.inputs, "Value", "VECTOR"))
    t.link(base, mark.inputs["Index"])
    points = t.store(stem.outputs[0], ATTR_HEAD, "FLOAT_VECTOR", _socket(mark.outputs, "Value", "VECTOR"))
    points = t.store(points, ATTR_STEM, "FLOAT", base)
    base = t.attribute(ATTR_STEM, "FLOAT")
    tip = t.middle(mesh, t.math("ADD", base, float(2 * n)))
    root = t.middle(mesh, base)
    if leafy:
        points = t.store(points, ATTR_LEAF, "FLOAT", t.sample(mesh, t.attribute(ATTR_LEAF, "FLOAT"), base, "FLOAT"))
        points = t.store(points, ATTR_FOOT_DIR, "FLOAT_VECTOR",
                         t.vmath("SUBTRACT", t.middle(mesh, t.math("ADD", base, 2.0)), root))
    points = t.store(points, ATTR_TIP_DIR, "FLOAT_VECTOR",
                     t.vmath("SUBTRACT", tip, t.middle(mesh, t.math("ADD", base, float(2 * n - 2)))))
    points = t.store(points, ATTR_TIP, "FLOAT_VECTOR", tip)
    if seeded:  # (a spike over the top segment, a panicle over the top two: ``shapes.SPAN_SCALED``)
        points = t.store(points, ATTR_SEED_BASE, "FLOAT_VECTOR", t.middle(mesh, t.math("ADD", base, float(2 * n - 4))))
        points = t.store(points, ATTR_SPIKE_BASE, "FLOAT_VECTOR", t.middle(mesh, t.math("ADD", base, float(2 * n - 2))))
    placed = t.node("GeometryNodeSetPosition")  # on its root (the plants stand there)
    t.link(points, placed.inputs["Geometry"])
    t.link(root, placed.inputs["Position"])
    return placed.outputs[0]


def _source_geometry(t: _Tree, source):
    """The geometry of an Object or a Collection (the collection's objects as they are placed in it)."""
    if isinstance(source, bpy.types.Collection):
        info = t.node("GeometryNodeCollectionInfo", transform_space="ORIGINAL")
        info.inputs["Collection"].default_value = source
        info.inputs["Separate Children"].default_value = False
        info.inputs["Reset Children"].default_value = False
        return info.outputs[0]
    info = t.node("GeometryNodeObjectInfo", transform_space="ORIGINAL")
    info.inputs["Object"].default_value = source
    return info.outputs["Geometry"]


def _along(t: _Tree, vector, turn_angle):
    """The rotation that takes an instance's +Z along ``vector`` (a stem's segment), turned about
    it by ``turn_angle`` (the stem's facing)."""
    align = t.node("FunctionNodeAlignRotationToVector", axis="Z")
    t.link(vector, align.inputs["Vector"])
    turn = t.node("FunctionNodeAxisAngleToRotation")
    turn.inputs["Axis"].default_value = (0.0, 0.0, 1.0)
    t.link(turn_angle, turn.inputs["Angle"])
    rotate = t.node("FunctionNodeRotateRotation", rotation_space="LOCAL")
    t.link(align.outputs[0], rotate.inputs["Rotation"])
    t.link(turn.outputs[0], rotate.inputs["Rotate By"])
    return rotate.outputs[0]


def _instances(t: _Tree, points, kind: int, source):
    """Species ``kind``'s heads: ``source`` on its points that carry one (a size), turned to the
    stem, turned about it."""
    mine_kind, size, turn_angle, _first = t.head()
    mine = t.math("MULTIPLY", t.any_of(mine_kind, [kind]), t.math("GREATER_THAN", size, 0.0))
    rotation = _along(t, t.attribute(ATTR_TIP_DIR, "FLOAT_VECTOR"), turn_angle)
    radius = t.node("GeometryNodeInputRadius").outputs[0]
    place = t.node("GeometryNodeInstanceOnPoints")
    t.link(points, place.inputs["Points"])
    t.link(mine, place.inputs["Selection"])
    t.link(_source_geometry(t, source), place.inputs["Instance"])
    t.link(rotation, place.inputs["Rotation"])
    t.link(radius, place.inputs["Scale"])
    return place.outputs[0]


def _seed_heads(t: _Tree, roots, kind: int, source, even: bool = False):
    """Species ``kind``'s seed heads: ``source`` (``shapes.SEED_SHAPES``: z 0..1 its span, 1 wide)
    scaled to its span on each stem: a panicle (``even``, scaled evenly by the span) the top two
    segments (from the joint n - 2 to the tip, the spindle the far grass draws), a spike the top
    one, as wide as the seed head (``size``); turned about the stem by its facing."""
    mine_kind, size, turn_angle, _first = t.head()
    mine = t.math("MULTIPLY", t.any_of(mine_kind, [kind]), t.math("GREATER_THAN", size, 0.0))
    base = t.attribute(ATTR_SEED_BASE if even else ATTR_SPIKE_BASE, "FLOAT_VECTOR")
    span = t.vmath("SUBTRACT", t.attribute(ATTR_TIP, "FLOAT_VECTOR"), base)
    moved = t.node("GeometryNodeSetPosition")
    t.link(roots, moved.inputs["Geometry"])
    t.link(base, moved.inputs["Position"])
    rotation = _along(t, span, turn_angle)
    scale = t.node("ShaderNodeCombineXYZ")
    length = t.vmath("LENGTH", span, None, out="Value")
    t.link(length if even else size, scale.inputs["X"])
    t.link(length if even else size, scale.inputs["Y"])
    t.link(length, scale.inputs["Z"])
    place = t.node("GeometryNodeInstanceOnPoints")
    t.link(moved.outputs[0], place.inputs["Points"])
    t.link(mine, place.inputs["Selection"])
    t.link(_source_geometry(t, source), place.inputs["Instance"])
    t.link(rotation, place.inputs["Rotation"])
    t.link(scale.outputs[0], place.inputs["Scale"])
    return place.outputs[0]


def _leaves(t: _Tree, roots, leaves: list):
    """The leaves of every species ``k`` with ``leaves[k]`` (an Object: a unit tuft,
    ``tufts.leaf_mesh``; None: none) on the roots of its stems that have leaves (``wg_leaf`` > 0),
    each tuft's +Z along its stem's first segment (the tuft rocks with its tiller), turned about it
    by the stem's facing, scaled by ``wg_leaf``: one Instance on Points picking each stem's tuft
    from the species' (a node per species cost a pass over every stem each)."""
    kinds = [k + 1 for k, leaf in enumerate(leaves) if leaf is not None]
    sources = t.node("GeometryNodeGeometryToInstance")
    for k in reversed(kinds):  # (a multi-input socket lists its links last linked first: species order)
        t.link(_source_geometry(t, leaves[k - 1]), sources.inputs[0])
    mine_kind, _size, turn_angle, _first = t.head()
    which = None  # the stem's tuft: how many leafy species come before its own (its kind among them)
    for k in kinds[1:]:
        past = t.math("GREATER_THAN", mine_kind, k - 0.5)
        which = past if which is None else t.math("ADD", which, past)
    length = t.attribute(ATTR_LEAF, "FLOAT")
    rotation = _along(t, t.attribute(ATTR_FOOT_DIR, "FLOAT_VECTOR"), turn_angle)
    place = t.node("GeometryNodeInstanceOnPoints")
    t.link(roots, place.inputs["Points"])
    t.link(t.math("GREATER_THAN", length, 0.0), place.inputs["Selection"])
    t.link(sources.outputs[0], place.inputs["Instance"])
    place.inputs["Pick Instance"].default_value = True
    if which is not None:
        t.link(which, place.inputs["Instance Index"])
    else:
        place.inputs["Instance Index"].default_value = 0
    t.link(rotation, place.inputs["Rotation"])
    t.link(length, place.inputs["Scale"])
    return place.outputs[0]


def _bend_along(t: _Tree, strips, roots, kind: int, source, n: int):
    """Species ``kind``'s plants: ``source`` (its height H from its lowest to its highest point)
    stood on each root and bent along the stem: a point at height z of the source goes to the
    stem's centre line at arc share z / H (the joints the solver bent; the root stays, the
    stem's length is the plant's height, its segments keep theirs), its x and y along the strip's
    side and its normal at that joint, scaled by the stem's length / H."""
    asset = t.node("GeometryNodeRealizeInstances")
    t.link(_source_geometry(t, source), asset.inputs[0])
    local = t.node("GeometryNodeStoreNamedAttribute", data_type="FLOAT_VECTOR", domain="POINT")
    local.inputs["Name"].default_value = ATTR_LOCAL
    t.link(asset.outputs[0], local.inputs["Geometry"])
    t.link(t.node("GeometryNodeInputPosition").outputs[0], _socket(local.inputs, "Value", "VECTOR"))
    box = t.node("GeometryNodeBoundBox")
    t.link(asset.outputs[0], box.inputs[0])
    low, high = t.node("ShaderNodeSeparateXYZ"), t.node("ShaderNodeSeparateXYZ")
    t.link(box.outputs["Min"], low.inputs[0])
    t.link(box.outputs["Max"], high.inputs[0])
    height = t.math("MAXIMUM", t.math("SUBTRACT", high.outputs["Z"], low.outputs["Z"]), 1e-6)
    mine = t.any_of(t.head()[0], [kind])
    place = t.node("GeometryNodeInstanceOnPoints")
    t.link(roots, place.inputs["Points"])
    t.link(mine, place.inputs["Selection"])
    t.link(local.outputs[0], place.inputs["Instance"])
    real = t.node("GeometryNodeRealizeInstances")
    t.link(place.outputs[0], real.inputs[0])
    # each point of each plant: its stem (wg_base), the stem's length (wg_head's size), its place in the source
    xyz = t.node("ShaderNodeSeparateXYZ")
    t.link(t.attribute(ATTR_LOCAL, "FLOAT_VECTOR"), xyz.inputs[0])
    _kind, length, _turn, stem = t.head()
    share = t.math("DIVIDE", t.math("SUBTRACT", xyz.outputs["Z"], low.outputs["Z"]), height)
    along = t.math("MULTIPLY", t.math("MINIMUM", t.math("MAXIMUM", share, 0.0), 1.0), float(n))
    joint = t.math("FLOOR", t.math("MINIMUM", along, n - 1e-4))
    frac = t.math("SUBTRACT", along, joint)
    left = t.math("ADD", stem, t.math("MULTIPLY", joint, 2.0))
    here, above = t.middle(strips, left), t.middle(strips, t.math("ADD", left, 2.0))
    point = t.vmath("ADD", here, t.vmath("SCALE", t.vmath("SUBTRACT", above, here), None, scale=frac))
    tangent = t.vmath("NORMALIZE", t.vmath("SUBTRACT", above, here), None)
    side = t.vmath("SUBTRACT", t.sample(strips, t.position(), t.math("ADD", left, 1.0)),
                   t.sample(strips, t.position(), left))
    side = t.vmath("NORMALIZE", t.vmath("SUBTRACT", side, t.vmath(
        "SCALE", tangent, None, scale=t.vmath("DOT_PRODUCT", side, tangent, out="Value"))), None)
    normal = t.vmath("CROSS_PRODUCT", tangent, side)
    scale = t.math("DIVIDE", length, height)
    offset = t.vmath("ADD", t.vmath("SCALE", side, None, scale=t.math("MULTIPLY", xyz.outputs["X"], scale)),
                     t.vmath("SCALE", normal, None, scale=t.math("MULTIPLY", xyz.outputs["Y"], scale)))
    bend = t.node("GeometryNodeSetPosition")
    t.link(real.outputs[0], bend.inputs["Geometry"])
    t.link(t.vmath("ADD", point, offset), bend.inputs["Position"])
    return bend.outputs[0]


ROLE_HEAD, ROLE_GROUP, ROLE_MATERIAL = owned.ROLE_HEAD, owned.ROLE_HEAD_GROUP, owned.ROLE_HEAD_MATERIAL
_SHAPES = shapes.MESH_SHAPES + shapes.SEED_SHAPES  # Windgrass's own head meshes
ROLE_LEAVES = owned.ROLE_LEAVES


def _key(k: int) -> str:
    return owned.slot_key(ROLE_HEAD, k)


def own_collection(row):
    """The artist's collection a species row names (``plant``), or None; a name that names no
    collection is said once (the species then draws Windgrass's own)."""
    name = row["plant"]
    if not name:
        return None
    found = bpy.data.collections.get(name)
    if found is None:
        warn_once(f"species '{row['name']}': Own Plant names no collection '{name}' in this file; what it "
                  "names is not drawn (its stems are)")
    return found


def plant_shapes(params: Params) -> engine_plants.Plants:
    """The species drawn as the artist's own plant (Drawn As Plant), each its collection's
    triangles as the heads' tree places them, coloured by their materials (a Principled BSDF's
    Base Color, else the viewport colour), for the cards' atlas (``plants.py``)."""
    rows = params.species()
    kind = shapes.kinds(rows)
    found = []
    for k, row in enumerate(rows):
        own = own_collection(row) if kind[k] == shapes.PLANT else None
        if own is not None:
            found.append((k, _triangles(own)))
    return engine_plants.Plants(tuple(found))


def _triangles(collection) -> engine_plants.PlantShape:
    """A collection's mesh objects as triangles (their placement in the collection), coloured: their
    meshes as saved (the cards draw no modifier of the plant's objects)."""
    points, triangles, colours, base = [], [], [], 0
    offset = np.array(collection.instance_offset, np.float64)
    for obj in collection.all_objects:
        if obj.type != "MESH" or obj.data is None:
            continue
        mesh = obj.data
        mesh.calc_loop_triangles()
        co = np.empty(3 * len(mesh.vertices), np.float64)
        mesh.vertices.foreach_get("co", co)
        place = np.array(obj.matrix_world, np.float64)
        points.append(co.reshape(-1, 3) @ place[:3, :3].T + place[:3, 3] - offset)
        tri = np.empty(3 * len(mesh.loop_triangles), np.int64)
        mesh.loop_triangles.foreach_get("vertices", tri)
        slot = np.empty(len(mesh.loop_triangles), np.int64)
        mesh.loop_triangles.foreach_get("material_index", slot)
        palette = np.array([_colour(m.material if m else None) for m in obj.material_slots] or [_colour(None)])
        triangles.append(tri.reshape(-1, 3) + base)
        colours.append(palette[np.clip(slot, 0, len(palette) - 1)])
        base += len(mesh.vertices)
    if not points:
        return engine_plants.PlantShape.of(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    return engine_plants.PlantShape.of(np.concatenate(points), np.concatenate(triangles), np.concatenate(colours))


def _colour(material) -> tuple[float, float, float]:
    """A material's colour as the cards show it (linear RGB): its Principled BSDF's Base Color
    when nothing feeds it, else its viewport colour; no material: Blender's default grey."""
    if material is None:
        return (0.8, 0.8, 0.8)
    tree = material.node_tree
    for node in (tree.nodes if tree is not None else ()):
        if node.bl_idname == "ShaderNodeBsdfPrincipled" and not node.inputs["Base Color"].is_linked:
            return tuple(node.inputs["Base Color"].default_value[:3])
    return tuple(material.diffuse_color[:3])


def owns(data) -> bool:
    """``data`` is one of the field's heads' datablocks (a head or leaves object, the node group)."""
    return isinstance(data, (bpy.types.Object, bpy.types.NodeTree)) \
        and data.get("wg_role") in (ROLE_HEAD, ROLE_LEAVES, ROLE_GROUP)


def group_of(item):
    """The field's heads' node group, or None."""
    tree = owned.registered(item).get(ROLE_GROUP)
    return tree if isinstance(tree, bpy.types.NodeTree) else None


def remove(item) -> None:
    """Delete the field's head objects, their meshes and its node group (its material stays:
    ``scene.remove_datablocks`` deletes the materials)."""
    reg = owned.registered(item)
    for key, data in reg.items():
        if isinstance(data, bpy.types.Object) and data.get("wg_role") in (ROLE_HEAD, ROLE_LEAVES):
            mesh = data.data
            bpy.data.objects.remove(data, do_unlink=True)
            if mesh is not None and mesh.users == 0:
                bpy.data.meshes.remove(mesh)
        elif isinstance(data, bpy.types.NodeTree) and key == ROLE_GROUP:
            bpy.data.node_groups.remove(data)


def sources_key(params: Params) -> str:
    """What the heads' objects and node group are made from (each species' kind, head shape, Own
    Plant and how it is drawn, leaves; the stems' segments): the field's heads are made again when
    it changes, and kept through any other edit (their colours are written in place)."""
    rows = params.species()
    kind = shapes.kinds(rows)
    return repr([(int(kind[k]), r["head_shape"], r["plant"], r["plant_mode"], r.get("leaves", "none"))
                 for k, r in enumerate(rows)] + [int(params.blade.segments)])


def build(item, params: Params, uid: str, base: str, leaf_material=None):
    """The field's heads, leaves and plants made anew (after ``remove``): a head object per species
    with Windgrass flower meshes, a leaves object per species with leaves (``leaf_material``: the
    blades'), the artist's collections as they are, and the node group that draws them on the
    stems; None (and nothing made) when no species has any."""
    rows = params.species()
    leaves: list = [None] * len(rows)
    for k, row in enumerate(rows):
        if row.get("leaves", "none") in tufts.LEAF_SHAPES:
            obj = _leaves_object(f"{base} {row['name'] or 'species'} leaves", row, params, leaf_material)
            owned.tag(obj, uid, ROLE_LEAVES, k)
            owned.tag(obj.data, uid, ROLE_LEAVES, k)
            owned.record(item, owned.slot_key(ROLE_LEAVES, k), obj)
            leaves[k] = obj
    kind = shapes.kinds(rows)
    sources: list = [None] * len(rows)
    material = None
    for k, row in enumerate(rows):
        own = own_collection(row) if kind[k] != shapes.NONE else None
        if own is not None:
            sources[k] = (PLANT if kind[k] == shapes.PLANT else HEAD, own)
        elif kind[k] in (shapes.HEAD, shapes.SEED) and row["head_shape"] in _SHAPES:
            material = material or _material(item, uid, base)
            obj = _head_object(f"{base} {row['name'] or 'species'} head", row, material)
            owned.tag(obj, uid, ROLE_HEAD, k)
            owned.tag(obj.data, uid, ROLE_HEAD, k)
            owned.record(item, _key(k), obj)
            seed = SEED_SPAN if row["head_shape"] in shapes.SPAN_SCALED else SEED
            sources[k] = (seed if kind[k] == shapes.SEED else HEAD, obj)
    if all(s is None for s in sources + leaves):
        return None
    tree = build_group(f"{base} {GROUP_NAME.lower()}", sources, int(params.blade.segments), leaves)
    owned.tag(tree, uid, ROLE_GROUP)
    owned.record(item, ROLE_GROUP, tree)
    return tree


def _material(item, uid: str, base: str) -> bpy.types.Material:
    """The field's flower material (made once)."""
    found = owned.registered(item).get(ROLE_MATERIAL)
    if isinstance(found, bpy.types.Material):
        return found
    material = head_material(f"{base} flowers")
    owned.tag(material, uid, ROLE_MATERIAL)
    owned.record(item, ROLE_MATERIAL, material)
    return material


def _head_object(name: str, row, material) -> bpy.types.Object:
    """An object (in no scene: the modifier instances it) of a Windgrass head in its colours."""
    mesh = _head_mesh(name, row["head_shape"], row["head_color"])
    mesh.materials.append(material)
    return bpy.data.objects.new(mesh.name, mesh)


def _leaves_object(name: str, row, params: Params, material) -> bpy.types.Object:
    """An object (in no scene: the modifier instances it) of a species' unit tuft of leaves, with
    the blade material's UV maps: along the leaf, and its tint and shade (``_write_tints``)."""
    m = tufts.leaf_mesh(row["leaves"])
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(m.vertices.tolist(), [], m.faces)
    corners = _corner_vertices(mesh)
    mesh.uv_layers.new(name="UVMap")
    meshes.write_uv(mesh, "UVMap", np.stack([np.full(len(corners), 0.5, np.float32), m.v[corners]], axis=1))
    for data_uv in (materials.UV_TINT_RG, materials.UV_TINT_BS):
        mesh.uv_layers.new(name=data_uv, do_init=False)
    _write_tints(mesh, m, row["color"], float(params.blade.dry_tips))
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    if material is not None:
        mesh.materials.append(material)
    mesh.update()
    return bpy.data.objects.new(mesh.name, mesh)


def _corner_vertices(mesh) -> np.ndarray:
    corners = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    return corners


def _write_tints(mesh, m, colour, dry: float) -> None:
    """A leaves mesh's ``wg_tint_rg`` and ``wg_tint_bs`` per corner, as the blade strips carry
    them (``frame.blade_tints``): the species' colour (straw on a dead leaf), each leaf's shade."""
    corners = _corner_vertices(mesh)
    rgb = m.tints(colour, dry)[corners]
    meshes.write_uv(mesh, materials.UV_TINT_RG, rgb[:, :2])
    bs = np.stack([rgb[:, 2], m.shade[corners]], axis=1).astype(np.float32)
    meshes.write_uv(mesh, materials.UV_TINT_BS, bs)


def carriers(marks: np.ndarray) -> np.ndarray:
    """(vertices,) float32 ``wg_carry`` of an object's marks (``heads.tip_marks``' rows of its
    vertices): how many stems carry something, then each one's first vertex (a marked vertex
    whose index, modulo the object's vertex count, is its own: a plant marks every vertex of its
    strip with its first one's)."""
    count = len(marks)
    own = np.arange(count, dtype=np.int64)
    first = np.flatnonzero((marks[:, 0] > 0.5) & (np.mod(marks[:, 3].astype(np.int64), max(count, 1)) == own))
    out = np.zeros(count, np.float32)
    if count:
        out[0] = len(first)
        out[1:1 + len(first)] = first
    return out


def write_marks(mesh, marks: np.ndarray) -> None:
    """The engine's marks (``heads.tip_marks``, (vertices, 5)) into the slot mesh's ``wg_head``
    (the first three), ``wg_stem`` and ``wg_leaf``, and the stems that carry something
    (``wg_carry``, ``carriers``)."""
    for name, kind, field, values in ((ATTR_HEAD, "FLOAT_VECTOR", "vector", marks[:, :3]),
                                      (ATTR_STEM, "FLOAT", "value", marks[:, 3]),
                                      (ATTR_LEAF, "FLOAT", "value", marks[:, 4]),
                                      (ATTR_CARRY, "FLOAT", "value", carriers(marks))):
        attribute = mesh.attributes.get(name)
        if attribute is None or attribute.data_type != kind:
            if attribute is not None:
                mesh.attributes.remove(attribute)
            attribute = mesh.attributes.new(name, kind, "POINT")
        attribute.data.foreach_set(field, np.ascontiguousarray(values, dtype=np.float32).ravel())


def attach(obj, tree) -> None:
    """The heads' modifier on a blade slot object."""
    mod = obj.modifiers.new(MODIFIER, "NODES")
    mod.node_group = tree


def update_colours(item, params: Params) -> None:
    """Each Windgrass head mesh in its species' head colour, each leaves mesh in its species'
    colour (a look edit: nothing rebuilt)."""
    rows = params.species()
    for obj in owned.registered(item).values():
        if isinstance(obj, bpy.types.Object) and obj.get("wg_role") == ROLE_LEAVES and obj.data is not None:
            k = int(obj.get("wg_slot", -1))
            if 0 <= k < len(rows) and rows[k].get("leaves", "none") in tufts.LEAF_SHAPES:
                tuft = tufts.leaf_mesh(rows[k]["leaves"])
                if len(obj.data.vertices) == len(tuft.vertices) and materials.UV_TINT_RG in obj.data.uv_layers:
                    _write_tints(obj.data, tuft, rows[k]["color"], float(params.blade.dry_tips))
                    obj.data.update()
        if not isinstance(obj, bpy.types.Object) or obj.get("wg_role") != ROLE_HEAD or obj.data is None:
            continue
        k = int(obj.get("wg_slot", -1))
        if not 0 <= k < len(rows) or rows[k]["head_shape"] not in _SHAPES:
            continue
        mesh, m = obj.data, shapes.head_mesh(rows[k]["head_shape"])
        if len(mesh.vertices) != len(m.vertices) or ATTR_COLOR not in mesh.attributes:
            continue
        _write_colours(mesh, m, rows[k]["head_shape"], rows[k]["head_color"])
        mesh.update()
