"""windgrass.wind_force_add: the active field's wind for Blender's Hair and Cloth Dynamics (5.2+).

Makes the field's wind map, an effector in the file's collection Windgrass Wind
(``bridge/wind_force.py``), and sets that collection as the Effectors Collection of the active
object's Hair Dynamics or Cloth Dynamics.
"""

import bpy

from ..grass_addon.bridge import runtime
from ._common import active_field, has_active_field, reported


class WINDGRASS_OT_wind_force_add(bpy.types.Operator):
    """Blow Blender's Hair Dynamics and Cloth Dynamics with the active field's wind"""

    bl_idname = "windgrass.wind_force_add"
    bl_label = "Blow Hair and Cloth"
    bl_description = ("Make the active grass field's wind (mean, turbulence, gusts, force fields) an effector of "
                      "Hair Dynamics and Cloth Dynamics (Blender 5.2+), in the collection Windgrass Wind, and set "
                      "it as the active object's dynamics' Effectors Collection")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        item = active_field(scene)
        obj = context.active_object
        name, linked = runtime.blow_physics(scene, item, obj)
        if linked:
            self.report({"INFO"}, f"'{obj.name}' blows in the wind of '{item.name}' (its dynamics' Effectors "
                                  f"Collection: '{name}')")
        else:
            self.report({"INFO"}, f"The wind of '{item.name}' is in the collection '{name}': choose it as the "
                                  "Effectors Collection of a Hair Dynamics or Cloth Dynamics modifier")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_wind_force_add,)
