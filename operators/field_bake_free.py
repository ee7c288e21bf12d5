"""windgrass.field_bake_free: free the active field's bake, back to the live simulation."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import properties
from ._common import active_field, reported


class WINDGRASS_OT_field_bake_free(bpy.types.Operator):
    """Free the bake of the active grass field (its cache file too): back to the live simulation"""

    bl_idname = "windgrass.field_bake_free"
    bl_label = "Free Grass Bake"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        item = properties.active_field(context.scene) if context.scene is not None else None
        return item is not None and item.get("wg_bake") is not None

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        runtime.free_bake(scene, item)
        self.report({"INFO"}, f"Freed the bake of '{item.name}': live again")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_bake_free,)
