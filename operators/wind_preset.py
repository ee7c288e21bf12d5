"""windgrass.wind_preset: set the wind type and what the type implies (schema.wind_preset:
mean speed, turbulence)."""

import bpy

from ..grass_addon.bridge.runtime import animation, properties, schema
from ._common import active_field, has_active_field, reported


def _items():
    def text(kind):
        values = ", ".join(f"{name.split('.')[1]} {value:g} {schema.BY_NAME[name].unit}".rstrip()
                           for name, value in schema.wind_preset(kind).items() if name != "wind.type")
        return f"{kind.replace('_', ' ').capitalize()}: {values}"

    return [(t, t.replace("_", " ").capitalize(), text(t)) for t in schema.WIND_TYPES]


def _animated(scene, item, key: str) -> bool:
    """True when ``item.wind.<key>`` has an F-curve (its keyframes override a value set here)."""
    return key in animation.wind_fcurves(scene, item)


class WINDGRASS_OT_wind_preset(bpy.types.Operator):
    """Set the active field's wind type with its nominal mean speed and turbulence"""

    bl_idname = "windgrass.wind_preset"
    bl_label = "Grass Wind Preset"
    bl_description = "Set the wind type of the active grass field with its nominal speed and turbulence"
    bl_options = {"REGISTER", "UNDO"}
    bl_property = "type"

    type: bpy.props.EnumProperty(name="Wind Type", items=_items(), default=schema.BY_NAME["wind.type"].default)

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = active_field(context.scene)
        overrides = schema.wind_preset(self.type)  # {"wind.type": ..., "wind.speed": ..., ...}
        with properties.batch(item):
            for name, value in overrides.items():
                p = schema.BY_NAME[name]
                setattr(properties.group(item, p.section), p.key, properties.to_blender(p, value))
        speed = overrides["wind.speed"]
        if _animated(context.scene, item, "speed"):
            self.report({"WARNING"}, f"Wind speed is keyframed: its keyframes override the preset {speed:g} m/s")
        else:
            self.report({"INFO"}, f"Wind of '{item.name}': {self.type.replace('_', ' ')}, {speed:g} m/s")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_wind_preset,)
