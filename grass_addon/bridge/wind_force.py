"""One wind for Blender's own physics: the node group Windgrass Wind and the fields' wind maps.

Blender 5.2 and later simulate hair and cloth in Geometry Nodes (the Hair Dynamics and Cloth
Dynamics assets) and ship no wind. Windgrass gives them the meadow's:

* each frame ``write`` puts the wind the grass feels (``GrassField.wind_map``: mean, turbulence,
  gusts, force fields) on a grid mesh, the field's wind map, in world space (as the field's
  ground places it), with the attributes ``wind`` (m/s) and ``wind_speed``;
* the map's modifier (node group Windgrass Wind Effector) makes it an effector (Blender's Set
  Effector asset) of the node group Windgrass Wind: Blender's Custom Force asset whose force at
  every simulated point is the drag F = Drag |u| u of the map's wind there (Sample Nearest
  Surface: linear between grid points, the edge's value beyond the field), u = the wind minus
  the point's velocity (``wind_map.drag_force`` is its numpy twin);
* the maps are in the collection Windgrass Wind (in no scene), which Hair Dynamics' and Cloth
  Dynamics' Effectors Collection takes: ``link_into`` sets it on an object's dynamics.

The map is also what an artist's own node trees read of the field (Object Info of the map, or
Collection Info of Windgrass Wind; Map for Node Trees makes it, on any Blender): its points lie on
the field's ground, each with the attributes ``FIELD_ATTRIBUTES`` names (``wind_map.FieldMap``).
"""

from __future__ import annotations

import os

import bpy
import numpy as np

from .. import wind_map as engine_map
from . import owned, pools

GROUP_NAME = "Windgrass Wind"  # Map (Geometry), Drag -> Force (an Effectors bundle)
EFFECTOR_GROUP = "Windgrass Wind Effector"  # the map's modifier: its Force set as the map's effector
COLLECTION = "Windgrass Wind"  # the fields' maps: what the dynamics' Effectors Collection takes
MODIFIER = "Windgrass Wind"
ATTR_WIND, ATTR_SPEED = "wind", "wind_speed"
FIELD_ATTRIBUTES = {  # the map's point attributes (world space, metres) and what each is
    "wind": "the wind there (m/s, a vector)",
    "wind_speed": "its speed (m/s)",
    "height": "how high the grass's tops stand at rest (m; 0 where none grows)",
    "bend": "how far wind and colliders bend the grass from its rest shape (radians)",
    "flat": "how flat colliders trampled it (0 standing .. 1 flat)",
    "tip": "where the grass's tops are (a position)",
    "species": "which species most of its blades are (0, 1, ..; -1: none grows)",
}
ROLE_MAP = owned.ROLE_WIND_MAP
ASSET_FILE = ("assets", "nodes", "geometry_nodes_dynamics_assets.blend")
ASSETS = ("Custom Force", "Set Effector")  # Blender's own, appended from its bundled file once
DYNAMICS = ("Hair Dynamics", "Cloth Dynamics")  # Blender's assets that take effectors (names start so)
EFFECTORS_COLLECTION = "Effectors Collection"
DRAG_DEFAULT = 0.002  # kg/m: 5 m/s pushes 0.05 N on a point; a 0.5 m strand of Hair Dynamics' defaults bends ~0.27 m
MAP_KEY = "wg_map_grid"  # the map mesh's custom property: the grid and placement it was made for
NEEDS = "Blowing Blender's Hair and Cloth Dynamics needs Blender 5.2 or newer (this is {version})"


def available() -> bool:
    """Whether this Blender ships the Geometry Nodes physics the wind feeds (5.2 and later)."""
    return bpy.app.version >= (5, 2, 0) and os.path.exists(_asset_path())


def needs_note() -> str:
    return NEEDS.format(version=bpy.app.version_string)


def _asset_path() -> str:
    return os.path.join(bpy.utils.system_resource("DATAFILES"), *ASSET_FILE)


def map_object(item):
    """The field's wind map object, or None (not asked for)."""
    found = owned.recorded(item, ROLE_MAP)
    return found if isinstance(found, bpy.types.Object) else None


def ensure(item) -> bpy.types.Collection:
    """The field's wind map (made once; ``write`` fills it each frame) with its effector modifier
    (Blender 5.2+), in the file's Windgrass Wind collection; returns that collection."""
    obj = map_object(item)
    if obj is None:
        coll = item.collection
        uid = coll["wg_uid"]
        mesh = bpy.data.meshes.new(f"{coll.name} wind")
        obj = bpy.data.objects.new(mesh.name, mesh)
        owned.tag(obj, uid, ROLE_MAP)
        owned.tag(mesh, uid, ROLE_MAP)
        owned.record(item, ROLE_MAP, obj)
    if obj.modifiers.get(MODIFIER) is None and available():  # (an effector: Blender 5.2+'s physics)
        obj.modifiers.new(MODIFIER, "NODES").node_group = _effector_group()
    winds = bpy.data.collections.get(COLLECTION)
    if winds is None:
        winds = bpy.data.collections.new(COLLECTION)
        winds.use_fake_user = True  # (in no scene: kept for the dynamics that take it)
    if winds.objects.get(obj.name) is None:
        winds.objects.link(obj)
    return winds


def remove(item) -> None:
    """Delete the field's wind map (the dynamics then feel no wind from it)."""
    obj = map_object(item)
    if obj is None:
        return
    mesh = obj.data
    bpy.data.objects.remove(obj, do_unlink=True)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def write(item, field, frame: int) -> None:
    """The wind the field's grass feels at ``frame``, and the rest of ``FIELD_ATTRIBUTES``, into
    its map (a no-op without one)."""
    obj = map_object(item)
    if obj is None:
        return
    found = field.field_map(frame)
    grid = found.grid
    ground = owned.ground_object(item)
    place = np.array(ground.matrix_world if ground is not None else np.eye(4), dtype=np.float64)
    mesh = obj.data
    key = [grid.x0, grid.y0, grid.spacing, grid.nx, grid.ny, float(found.ground.sum()), *place.ravel().tolist()]
    if list(mesh.get(MAP_KEY, [])) != key:
        _make_grid(mesh, grid, found.ground, place)
        mesh[MAP_KEY] = key
    turn = place[:3, :3] / np.maximum(np.linalg.norm(place[:3, :3], axis=0), 1e-12)  # (the ground's rotation)
    wind = found.wind.astype(np.float64)
    pools.write_point_vectors(mesh, ATTR_WIND, wind @ turn[:, :2].T)
    pools.write_point_vectors(mesh, "tip", found.tip.astype(np.float64) @ place[:3, :3].T + place[:3, 3])
    pools.write_point_values(mesh, ATTR_SPEED, np.hypot(wind[:, 0], wind[:, 1]))
    pools.write_point_values(mesh, "height", found.height * _scale(place))
    pools.write_point_values(mesh, "bend", found.bend)
    pools.write_point_values(mesh, "flat", found.flat)
    pools.write_point_values(mesh, "species", found.species, "INT")
    mesh.update_tag()


def _scale(place: np.ndarray) -> float:
    """The ground's scale along its up axis (heights in world metres)."""
    return float(np.linalg.norm(place[:3, 2]))


def _make_grid(mesh, grid: engine_map.MapGrid, heights: np.ndarray, place: np.ndarray) -> None:
    """The map's grid of quads on the ground (``heights``) in world space (``place``: the field's
    ground's matrix)."""
    mesh.clear_geometry()
    points = np.column_stack([grid.points(), heights]) @ place[:3, :3].T + place[:3, 3]
    quads = grid.quads()
    mesh.vertices.add(grid.count)
    mesh.vertices.foreach_set("co", points.astype(np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update()


# ---------------------------------------------------------------------------- the node groups


def _asset(name: str) -> bpy.types.NodeTree:
    """Blender's asset ``name`` (Custom Force, Set Effector), appended from its bundled file once
    (marked, so an artist's own group of that name is never taken for it)."""
    for tree in bpy.data.node_groups:
        if tree.get("wg_asset") == name:
            return tree
    with bpy.data.libraries.load(_asset_path(), link=False) as (_, into):
        into.node_groups = [name]
    tree = into.node_groups[0]
    tree["wg_asset"] = name
    return tree


def _ours(name: str):
    tree = bpy.data.node_groups.get(name)
    return tree if tree is not None and tree.bl_idname == "GeometryNodeTree" and tree.get("wg_wind") else None


def _input(node, name: str, kind: str | None = None):
    return next(s for s in node.inputs if s.name == name and (kind is None or s.type == kind))


def _output(node, name: str, kind: str):
    return next(s for s in node.outputs if s.name == name and s.type == kind)


def _new_group(name: str, description: str) -> bpy.types.NodeTree:
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree["wg_wind"] = 1
    tree.description = description
    return tree


def _drag_socket(tree):
    drag = tree.interface.new_socket("Drag", in_out="INPUT", socket_type="NodeSocketFloat")
    drag.default_value, drag.min_value, drag.max_value = DRAG_DEFAULT, 0.0, 10.0
    drag.description = "F = Drag |u| u for the air's speed u past each simulated point (kg/m)"
    return drag


def wind_group() -> bpy.types.NodeTree:
    """Windgrass Wind: Map (a wind map's geometry), Drag (kg/m) -> Force, an Effectors bundle
    (Blender's Custom Force in field mode) whose force at each simulated point, in world space,
    is the drag of the map's wind there relative to the point's ``velocity``."""
    tree = _ours(GROUP_NAME)
    if tree is not None:
        return tree
    tree = _new_group(GROUP_NAME, "The Windgrass meadow's wind (mean, turbulence, gusts, force fields) as a force "
                      "for Hair Dynamics and Cloth Dynamics: F = Drag |u| u, u the wind past each point")
    face = tree.interface
    face.new_socket("Force", in_out="OUTPUT", socket_type="NodeSocketBundle")
    face.new_socket("Map", in_out="INPUT", socket_type="NodeSocketGeometry").description = (
        "A grass field's wind map (the collection Windgrass Wind holds them)")
    _drag_socket(tree)
    n, link = tree.nodes.new, tree.links.new
    group_in, group_out = n("NodeGroupInput"), n("NodeGroupOutput")
    sample = n("GeometryNodeSampleNearestSurface")  # (at the point's own position: the map is flat)
    sample.data_type = "FLOAT_VECTOR"
    wind = n("GeometryNodeInputNamedAttribute")
    wind.data_type = "FLOAT_VECTOR"
    wind.inputs["Name"].default_value = ATTR_WIND
    link(group_in.outputs["Map"], sample.inputs["Mesh"])
    link(_output(wind, "Attribute", "VECTOR"), _input(sample, "Value", "VECTOR"))
    velocity = n("GeometryNodeInputNamedAttribute")
    velocity.data_type = "FLOAT_VECTOR"
    velocity.inputs["Name"].default_value = "velocity"  # the point's (the XPBD solver keeps it; none: at rest)
    rel = n("ShaderNodeVectorMath")
    rel.operation = "SUBTRACT"
    link(_output(sample, "Value", "VECTOR"), rel.inputs[0])
    link(_output(velocity, "Attribute", "VECTOR"), rel.inputs[1])
    speed = n("ShaderNodeVectorMath")
    speed.operation = "LENGTH"
    link(rel.outputs[0], speed.inputs[0])
    gain = n("ShaderNodeMath")
    gain.operation = "MULTIPLY"
    link(speed.outputs["Value"], gain.inputs[0])
    link(group_in.outputs["Drag"], gain.inputs[1])
    force = n("ShaderNodeVectorMath")
    force.operation = "SCALE"
    link(rel.outputs[0], force.inputs[0])
    link(gain.outputs[0], force.inputs["Scale"])
    custom = n("GeometryNodeGroup")
    custom.node_tree = _asset("Custom Force")
    link(force.outputs[0], _input(custom, "Force", "VECTOR"))
    link(custom.outputs[0], group_out.inputs["Force"])
    _lay_out(tree)
    return tree


def _effector_group() -> bpy.types.NodeTree:
    """Windgrass Wind Effector, the map's modifier: its geometry with Windgrass Wind of itself set
    as its effector (Blender's Set Effector), which the dynamics' Effectors Collection collects."""
    tree = _ours(EFFECTOR_GROUP)
    if tree is not None:
        return tree
    tree = _new_group(EFFECTOR_GROUP, "A Windgrass wind map as an effector of Hair Dynamics and Cloth Dynamics")
    face = tree.interface
    face.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    face.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    _drag_socket(tree)
    n, link = tree.nodes.new, tree.links.new
    group_in, group_out = n("NodeGroupInput"), n("NodeGroupOutput")
    force = n("GeometryNodeGroup")
    force.node_tree = wind_group()
    link(group_in.outputs["Geometry"], force.inputs["Map"])
    link(group_in.outputs["Drag"], force.inputs["Drag"])
    effector = n("GeometryNodeGroup")
    effector.node_tree = _asset("Set Effector")
    link(group_in.outputs["Geometry"], _input(effector, "Geometry"))
    link(force.outputs["Force"], _input(effector, "Effector"))
    _input(effector, "Name").default_value = "windgrass"
    link(effector.outputs[0], group_out.inputs["Geometry"])
    _lay_out(tree)
    return tree


def _lay_out(tree) -> None:
    for i, node in enumerate(tree.nodes):
        node.location = (180 * i, 0)


# ---------------------------------------------------------------------------- the dynamics


def link_into(obj, winds) -> int:
    """The Windgrass Wind collection ``winds`` as the Effectors Collection of each Hair or Cloth
    Dynamics of ``obj``'s Geometry Nodes modifiers (the asset as the modifier itself, or a node of
    its tree) that has none; where one has its own collection already, the maps join it. Returns
    how many dynamics now blow (0: ``obj`` has none)."""
    count = 0
    for mod in getattr(obj, "modifiers", ()):
        group = getattr(mod, "node_group", None) if mod.type == "NODES" else None
        if group is None:
            continue
        if group.name.startswith(DYNAMICS):
            ident = next((i.identifier for i in group.interface.items_tree if i.item_type == "SOCKET"
                          and i.in_out == "INPUT" and i.name == EFFECTORS_COLLECTION), None)
            if ident is not None:
                _take(_ModifierInput(mod, ident), winds)
                count += 1
            continue
        for node in group.nodes:
            sub = getattr(node, "node_tree", None)
            if node.bl_idname != "GeometryNodeGroup" or sub is None or not sub.name.startswith(DYNAMICS):
                continue
            socket = next((s for s in node.inputs if s.name == EFFECTORS_COLLECTION), None)
            if socket is not None and not socket.is_linked:
                _take(socket, winds)
                count += 1
    if count:
        obj.update_tag()
    return count


class _ModifierInput:
    """A modifier's input value, read and written as a socket's ``default_value`` (Blender 5.2
    moved them to ``modifier.properties.inputs[identifier].value``)."""

    def __init__(self, mod, ident: str):
        self.mod, self.ident = mod, ident

    @property
    def default_value(self):
        return getattr(self.mod.properties.inputs, self.ident).value

    @default_value.setter
    def default_value(self, value) -> None:
        getattr(self.mod.properties.inputs, self.ident).value = value


def _take(slot, winds) -> None:
    """``slot``'s collection becomes ``winds``; one of the artist's own gets the maps instead."""
    own = slot.default_value
    if own is None or own == winds:
        slot.default_value = winds
        return
    for obj in winds.objects:
        if own.objects.get(obj.name) is None:
            own.objects.link(obj)
