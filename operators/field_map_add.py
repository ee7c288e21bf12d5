"""windgrass.field_map_add: the active field's map, for an artist's own Geometry Nodes.

Makes the field's map (``bridge/wind_force.py``): a grid on the field's ground whose points carry
the field's attributes each frame (``wind_force.FIELD_ATTRIBUTES``: wind, height, bend, flat, tip,
species), in the collection Windgrass Wind, for Object Info or Collection Info to read.
"""

import bpy

from ..grass_addon.bridge import runtime
from ._common import has_active_field, reported


class WINDGRASS_OT_field_map_add(bpy.types.Operator):
    """Put the active field's wind, height, bend, flatness, tops and species on a map node trees can read"""

    bl_idname = "windgrass.field_map_add"
    bl_label = "Map for Node Trees"
    bl_description = ("Make the active grass field's map: a grid on its ground whose points carry the attributes "
                      "wind, wind_speed, height, bend, flat, tip and species each frame, for your own Geometry "
                      "Nodes (Object Info of the map)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = runtime.properties.active_field(context.scene)
        obj = runtime.share_map(context.scene, item)
        names = ", ".join(runtime.wind_force.FIELD_ATTRIBUTES)
        self.report({"INFO"}, f"'{obj.name}' carries the field's attributes ({names}); read it with Object Info "
                              "in your node tree")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_map_add,)
