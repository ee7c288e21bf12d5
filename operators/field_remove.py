"""windgrass.field_remove: delete the active field and everything it made."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import properties
from ._common import active_field, has_active_field, reported


class WINDGRASS_OT_field_remove(bpy.types.Operator):
    """Delete the active grass field: its objects, meshes, materials, images and settings"""

    bl_idname = "windgrass.field_remove"
    bl_label = "Remove Grass Field"
    bl_description = "Delete the active grass field with every object, mesh, material and image it made"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    def invoke(self, context, event):
        return context.window_manager.invoke_confirm(self, event)

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        name = item.name
        runtime.remove_field(scene, item)
        properties.remove_item(scene, item)
        self.report({"INFO"}, f"Removed grass field '{name}'")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_remove,)
