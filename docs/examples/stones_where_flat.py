"""Stones where the grass lies flat: a Geometry Nodes tree of your own reading a Windgrass field.

Run it in Blender with a grass field in the scene (Text Editor > Run Script, or
``blender file.blend -P docs/examples/stones_where_flat.py``). It makes the active field's map
(Grass tab > Wind > Map for Node Trees) and an object "Stones" whose node tree is:

    Object Info (the map) -> Distribute Points on Faces (Density: Map Range of the map's
    attribute "flat", FLAT_FROM..1 -> 0..PER_M2) -> Instance on Points (an Ico Sphere, random
    rotation and scale) -> Realize Instances

so stones lie where a collider trampled the grass flat, and nowhere else; play the animation and
they follow the trail. Any attribute of the map (wind, wind_speed, height, bend, flat, tip,
species) can drive a tree the same way.
"""

import bpy

PER_M2 = 60.0  # stones a square metre where the grass is flat
FLAT_FROM = 0.5  # how flat the grass must be before a stone shows (0 standing .. 1 flat)
RADIUS = 0.04  # m


def field_map(scene) -> bpy.types.Object:
    """The active field's map, made if it has none."""
    bpy.ops.windgrass.field_map_add()
    root = scene.windgrass
    field = root.fields[min(max(root.active_index, 0), len(root.fields) - 1)]
    uid = field.collection["wg_uid"]
    return next(o for o in bpy.data.collections["Windgrass Wind"].objects if o.get("wg_uid") == uid)


def _socket(sockets, name: str, kind: str):
    return next(s for s in sockets if s.name == name and s.type == kind and s.enabled)


def stones_tree(map_object) -> bpy.types.NodeTree:
    tree = bpy.data.node_groups.new("Stones Where Flat", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, link = tree.nodes.new, tree.links.new
    info = n("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = map_object
    flat = n("GeometryNodeInputNamedAttribute")
    flat.data_type = "FLOAT"
    flat.inputs["Name"].default_value = "flat"
    density = n("ShaderNodeMapRange")
    density.clamp = True
    link(_socket(flat.outputs, "Attribute", "VALUE"), density.inputs["Value"])
    density.inputs["From Min"].default_value, density.inputs["From Max"].default_value = FLAT_FROM, 1.0
    density.inputs["To Min"].default_value, density.inputs["To Max"].default_value = 0.0, PER_M2
    scatter = n("GeometryNodeDistributePointsOnFaces")
    scatter.distribute_method = "RANDOM"
    link(info.outputs["Geometry"], scatter.inputs["Mesh"])
    link(density.outputs["Result"], scatter.inputs["Density"])
    stone = n("GeometryNodeMeshIcoSphere")
    stone.inputs["Radius"].default_value, stone.inputs["Subdivisions"].default_value = RADIUS, 1
    turn = n("FunctionNodeRandomValue")
    turn.data_type = "FLOAT_VECTOR"
    _socket(turn.inputs, "Max", "VECTOR").default_value = (6.283, 6.283, 6.283)
    size = n("FunctionNodeRandomValue")
    _socket(size.inputs, "Min", "VALUE").default_value, _socket(size.inputs, "Max", "VALUE").default_value = 0.6, 1.4
    place = n("GeometryNodeInstanceOnPoints")
    link(scatter.outputs["Points"], place.inputs["Points"])
    link(stone.outputs["Mesh"], place.inputs["Instance"])
    link(_socket(turn.outputs, "Value", "VECTOR"), place.inputs["Rotation"])
    link(_socket(size.outputs, "Value", "VALUE"), place.inputs["Scale"])
    real = n("GeometryNodeRealizeInstances")
    link(place.outputs["Instances"], real.inputs["Geometry"])
    link(real.outputs["Geometry"], n("NodeGroupOutput").inputs["Geometry"])
    for i, node in enumerate(tree.nodes):
        node.location = (200 * i, 0)
    return tree


def main() -> bpy.types.Object:
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Stones")
    obj = bpy.data.objects.new("Stones", mesh)
    scene.collection.objects.link(obj)
    obj.modifiers.new("Stones Where Flat", "NODES").node_group = stones_tree(field_map(scene))
    return obj


if __name__ == "__main__":
    main()
