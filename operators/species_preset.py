"""windgrass.species_preset: replace the species table by a preset (grass_addon/presets.py)."""

import bpy

from ..grass_addon.bridge.runtime import presets, properties
from ._common import has_active_field, reported


def _items():
    return [(n, n.capitalize(), presets.PRESET_HELP.get(n, n)) for n in presets.PRESET_NAMES]


class WINDGRASS_OT_species_preset(bpy.types.Operator):
    """Replace the active field's grass species by a preset mix"""

    bl_idname = "windgrass.species_preset"
    bl_label = "Grass Species Preset"
    bl_description = ("Replace the species of the active grass field by a preset mix (lawn, meadow, wild) and "
                      "take the preset's tussocks, patches and dry tips")
    bl_options = {"REGISTER", "UNDO"}
    bl_property = "preset"

    preset: bpy.props.EnumProperty(name="Preset", items=_items())

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = properties.active_field(context.scene)
        rows = presets.species_rows(self.preset)  # validated by the schema
        properties.write_rows(item, properties.table_param("blade.species"), rows)
        for name, value in presets.LOOKS[self.preset].items():
            section, key = name.split(".")
            setattr(properties.group(item, section), key, value)
        names = ", ".join(r["name"] for r in rows)
        self.report({"INFO"}, f"Species of '{item.name}': {names}")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_species_preset,)
