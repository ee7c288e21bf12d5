"""windgrass.field_rebuild: rebuild the active field's objects from its settings."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import properties
from ._common import active_field, has_active_field, refresh, reported


class WINDGRASS_OT_field_rebuild(bpy.types.Operator):
    """Rebuild the active grass field (layout, meshes, materials) from its settings"""

    bl_idname = "windgrass.field_rebuild"
    bl_label = "Rebuild Grass Field"
    bl_description = "Rebuild the active grass field's blades, cards and ground from its settings"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        properties.params_from_settings(item)  # a bad setting stops here, naming its key
        collection = runtime.build_field(scene, item, force=True)
        if collection is not None and item.collection is None:
            item.collection = collection
        refresh(scene)
        error = runtime.field_error(scene, item)
        if error:  # (built: the undo step must hold it; the panel says why the grass is hidden)
            self.report({"ERROR"}, f"Rebuilt grass field '{item.name}', but its grass is hidden: {error}")
        else:
            self.report({"INFO"}, f"Rebuilt grass field '{item.name}'")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_rebuild,)
