"""windgrass.field_bake: bake the active field to Alembic or USD caches beside the .blend (it then
plays and renders in any Blender; USD also in other renderers and pipelines)."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import WindgrassError, bake, properties
from ._common import has_active_field, reported

# Steps of a bake in the panel: each exports a part of the field's objects (progress and Esc
# between steps); each also simulates every frame again, so a few, not many.
UI_STEPS = 4


class WINDGRASS_OT_field_bake(bpy.types.Operator):
    """Bake the active grass field over a frame range into an Alembic or USD cache beside the .blend,
    as the scene camera sees it; the file then plays and renders the grass in a Blender without
    Windgrass, and a USD cache in other renderers"""

    bl_idname = "windgrass.field_bake"
    bl_label = "Bake Grass Field"
    bl_options = {"REGISTER", "UNDO"}

    frame_start: bpy.props.IntProperty(name="Start", min=0, description="First frame to bake (the scene's by default)")
    frame_end: bpy.props.IntProperty(name="End", min=0, description="Last frame to bake (the scene's by default)")
    format: bpy.props.EnumProperty(
        name="Format", default="alembic",
        items=[("alembic", "Alembic", "Alembic (.abc): Blender and most animation packages"),
               ("usd", "USD", "USD (.usdc): time-sampled points, velocities and extents for renderers and "
                              "pipelines outside Blender (Houdini, Omniverse, Unreal)")])

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    def _range(self, scene) -> None:
        if not self.properties.is_property_set("frame_start"):
            self.frame_start = scene.frame_start
        if not self.properties.is_property_set("frame_end"):
            self.frame_end = scene.frame_end

    def invoke(self, context, event):
        """In the UI: one group of objects per step, the progress in the cursor, Esc to stop."""
        scene = context.scene
        self._range(scene)
        try:
            self._baker = runtime.start_bake(scene, properties.active_field(scene), self.frame_start,
                                             self.frame_end, groups=UI_STEPS, fmt=self.format)
        except WindgrassError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        self.report({"INFO"}, "Baking the grass (Esc to stop)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        wm = context.window_manager
        if event.type == "ESC":
            self._end(context)
            try:
                self._baker.cancel()
            except ReferenceError:  # the scene is not the one the bake began in
                self._baker.abandon()
            self.report({"WARNING"}, "Bake stopped: nothing was kept, the grass is live")
            return {"CANCELLED"}
        if event.type != "TIMER":
            # Keys would reach Blender's undo and edits under the bake (Ctrl+Z): only the view moves.
            navigation = event.type.startswith(("MOUSE", "WHEEL", "TRACKPAD", "NDOF")) or event.type in (
                "MIDDLEMOUSE", "WINDOW_DEACTIVATE")
            return {"PASS_THROUGH"} if navigation else {"RUNNING_MODAL"}
        try:
            done = self._baker.step()
        except ReferenceError:  # what it bakes is gone (an undo slipped through): keep nothing
            self._end(context)
            self._baker.abandon()
            self.report({"WARNING"}, "Bake stopped: the field changed under it; nothing was kept")
            return {"CANCELLED"}
        except WindgrassError as exc:
            self._end(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm.progress_update(int(100 * self._baker.progress))
        if not done:
            return {"RUNNING_MODAL"}
        self._end(context)
        folder = self._baker.finish()
        runtime.write_read_me()
        self._done(properties.active_field(context.scene), folder)
        return {"FINISHED"}

    def _end(self, context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()

    def _done(self, item, folder) -> None:
        frames = self.frame_end - self.frame_start + 1
        size = bake.cache_size(folder)
        self.report({"INFO"}, f"Baked '{item.name}' frames {self.frame_start}-{self.frame_end} into {folder.name}/ "
                              f"({bake.FORMATS[self.format][2]}, {size / frames / 1e6:.2f} MB per frame)")
        if not item[bake.RECORD].get("seen", True):
            self.report({"WARNING"}, f"The scene camera sees none of '{item.name}' in frames {self.frame_start}-"
                                     f"{self.frame_end}: the bake holds no grass (aim the camera at the field)")

    @reported
    def execute(self, context):
        """From scripts: the whole bake at once."""
        scene = context.scene
        self._range(scene)
        item = properties.active_field(scene)
        folder = runtime.bake_field(scene, item, self.frame_start, self.frame_end, fmt=self.format)
        self._done(item, folder)
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_bake,)
