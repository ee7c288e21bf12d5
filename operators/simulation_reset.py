"""windgrass.simulation_reset: drop the active field's simulation state and simulate again."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import properties
from ._common import active_field, has_active_field, refresh, reported


class WINDGRASS_OT_simulation_reset(bpy.types.Operator):
    """Forget the simulated states of the active field and simulate the current frame again"""

    bl_idname = "windgrass.simulation_reset"
    bl_label = "Reset Grass Simulation"
    bl_description = ("Forget the active grass field's simulated states and saved states, "
                      "then simulate the current frame again (from its epoch's start, at rest)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        properties.params_from_settings(item)  # a bad setting stops here, naming its key
        runtime.reset_field(scene, item)
        refresh(scene)
        self.report({"INFO"}, f"Reset the simulation of '{item.name}' (frame {scene.frame_current})")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_simulation_reset,)
