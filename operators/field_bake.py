"""windgrass.field_bake and windgrass.field_bake_free: bake the active field to an Alembic cache
beside the .blend (it then plays in any Blender), and back to the live simulation."""

import bpy

from ..grass_addon.bridge import properties, runtime
from ._common import has_active_field, reported


class WINDGRASS_OT_field_bake(bpy.types.Operator):
    """Bake the active grass field over a frame range into an Alembic cache beside the .blend, as the
    scene camera sees it; the file then plays and renders the grass in a Blender without Windgrass"""

    bl_idname = "windgrass.field_bake"
    bl_label = "Bake Grass Field"
    bl_options = {"REGISTER", "UNDO"}

    frame_start: bpy.props.IntProperty(name="Start", min=0, description="First frame to bake (the scene's by default)")
    frame_end: bpy.props.IntProperty(name="End", min=0, description="Last frame to bake (the scene's by default)")

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    def invoke(self, context, event):
        scene = context.scene
        if not self.properties.is_property_set("frame_start"):
            self.frame_start = scene.frame_start
        if not self.properties.is_property_set("frame_end"):
            self.frame_end = scene.frame_end
        return self.execute(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = properties.active_field(scene)
        wm = context.window_manager
        wm.progress_begin(0, 1)
        try:
            path = runtime.bake_field(scene, item, self.frame_start, self.frame_end)
        finally:
            wm.progress_end()
        frames = self.frame_end - self.frame_start + 1
        size = path.stat().st_size
        self.report({"INFO"}, f"Baked '{item.name}' frames {self.frame_start}-{self.frame_end} to {path.name} "
                              f"({size / frames / 1e6:.2f} MB per frame)")
        return {"FINISHED"}


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
        item = properties.active_field(scene)
        runtime.free_bake(scene, item)
        self.report({"INFO"}, f"Freed the bake of '{item.name}': live again")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_bake, WINDGRASS_OT_field_bake_free)
