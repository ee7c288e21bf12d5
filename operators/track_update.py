"""windgrass.track_update: sample the active field's colliders and force fields over the frame range."""

import bpy

from ..grass_addon.bridge import properties, runtime, tracks
from ._common import has_active_field, refresh, reported


class WINDGRASS_OT_track_update(bpy.types.Operator):
    """Sample where the active field's colliders and force fields are at every frame"""

    bl_idname = "windgrass.track_update"
    bl_label = "Update Motion"
    bl_description = ("Step through the frame range and record where the active grass field's colliders are and "
                      "what its force fields do, so any frame shows the grass they pushed and trampled (saved with "
                      "the file; done by itself when they change)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = properties.active_field(scene)
        params = properties.params_from_settings(item, scene)
        wm = context.window_manager
        frames = tracks.frame_range(scene, params)
        wm.progress_begin(0, len(frames))
        try:
            changed = runtime.update_track(scene, item, progress=lambda done, total: wm.progress_update(done))
        finally:
            wm.progress_end()
        refresh(scene)
        if not (item.collider_collection or item.effector_collection):
            self.report({"INFO"}, f"'{item.name}' has no Colliders or Force Fields collection")
        elif changed:
            self.report({"INFO"}, f"Sampled the motion of '{item.name}' over {len(frames)} frames "
                                  f"({frames.start} to {frames.stop - 1})")
        else:
            self.report({"INFO"}, f"The motion of '{item.name}' is up to date")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_track_update,)
