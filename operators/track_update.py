"""windgrass.track_update: sample the active field's colliders and force fields over the frame range.

From the panel it runs a frame at a time (a modal operator on a timer): the status bar and the
progress cursor count the frames, Esc stops it and keeps the motion stored before. From a script
(``execute``) it samples everything at once.
"""

import time

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import WindgrassError, properties, tracks
from ._common import active_field, has_active_field, refresh, reported

STEP_S = 0.1  # seconds of sampling per timer tick: the window stays responsive to Esc


class WINDGRASS_OT_track_update(bpy.types.Operator):
    """Sample where the active field's colliders and force fields are at every frame"""

    bl_idname = "windgrass.track_update"
    bl_label = "Update Motion"
    bl_description = ("Step through the frame range and record where the active grass field's colliders are and "
                      "what its force fields do, so any frame shows the grass they pushed and trampled (saved with "
                      "the file; Esc stops it)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        params = properties.params_from_settings(item, scene)
        frames = tracks.frame_range(scene, params)
        changed = runtime.update_track(scene, item)
        refresh(scene)
        return self._done(item, changed, frames)

    def _done(self, item, changed: bool, frames) -> set[str]:
        if not (item.collider_collection or item.effector_collection):
            self.report({"INFO"}, f"'{item.name}' has no Colliders or Force Fields collection")
        elif changed:
            self.report({"INFO"}, f"Sampled the motion of '{item.name}' over {len(frames)} frames "
                                  f"({frames.start} to {frames.stop - 1})")
        else:
            self.report({"INFO"}, f"The motion of '{item.name}' is up to date")
        return {"FINISHED"}

    def invoke(self, context, event):
        scene = context.scene
        item = properties.active_field(scene)
        if item is None:  # (execute reports it)
            return self.execute(context)
        try:
            params = properties.params_from_settings(item, scene)
            wanted = tracks.fingerprint(scene, item, params)
        except WindgrassError:  # a bad setting: execute reports it
            return self.execute(context)
        if not wanted or tracks.stored_fingerprint(item) == wanted:
            return self.execute(context)
        runtime.terrain_of(scene, item, params)  # (the ground's height bounds the colliders' spheres)
        self._frames = tracks.frame_range(scene, params)
        self._steps = tracks.sampling(scene, item, params)
        self._wanted, self._uid = wanted, item.uid
        wm = context.window_manager
        wm.progress_begin(0, len(self._frames))
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._steps.close()  # (the scene goes back to its frame; the stored motion stays)
            self._finish(context)
            refresh(context.scene)
            self.report({"WARNING"}, "Update Motion stopped: the motion stored before is kept")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        started = time.perf_counter()
        while time.perf_counter() - started < STEP_S:
            try:
                done, total = next(self._steps)
            except StopIteration as finished:
                item = next((f for f in context.scene.windgrass.fields if f.uid == self._uid), None)
                self._finish(context)
                if item is None:
                    return {"CANCELLED"}
                runtime.store_track(context.scene, item, finished.value, self._wanted)
                refresh(context.scene)
                return self._done(item, True, self._frames)
            context.window_manager.progress_update(done)
            context.workspace.status_text_set(f"Windgrass: sampling the motion, frame {done} of {total} "
                                              "(Esc to stop)")
        return {"RUNNING_MODAL"}

    def _finish(self, context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


CLASSES = (WINDGRASS_OT_track_update,)
