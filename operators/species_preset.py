"""windgrass.species_preset: replace the species table by a preset (grass_addon/presets.py)."""

import bpy

from ..grass_addon.bridge.runtime import presets, properties, schema
from ._common import active_field, has_active_field, reported


def _items():
    return [(n, n.capitalize(), presets.PRESET_HELP.get(n, n)) for n in presets.PRESET_NAMES]


class WINDGRASS_OT_species_preset(bpy.types.Operator):
    """Replace the active field's grass species by a preset mix"""

    bl_idname = "windgrass.species_preset"
    bl_label = "Grass Species Preset"
    bl_description = ("Replace the species of the active grass field by a preset mix (lawn, meadow, wild) and, "
                      "unless With Its Look is off, take the preset's tussocks, patches, dry tips and floor")
    bl_options = {"REGISTER", "UNDO"}
    bl_property = "preset"

    preset: bpy.props.EnumProperty(name="Preset", items=_items())
    with_look: bpy.props.BoolProperty(
        name="With Its Look", default=True,
        description="Also take the preset's tussocks (Clumping), patches, dry tips and floor; off: the species "
                    "alone, every other setting as it was")

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = active_field(context.scene)
        rows = presets.species_rows(self.preset)  # validated by the schema
        properties.write_rows(item, properties.table_param("blade.species"), rows)
        changed = []
        for name, value in presets.LOOKS[self.preset].items() if self.with_look else ():
            section, key = name.split(".")
            owner = properties.group(item, section)
            if getattr(owner, key) != value:
                param = schema.BY_NAME[name]
                shown = value.title() if isinstance(value, str) else f"{value:g}"
                changed.append(f"{param.ui_name} {shown}")
            setattr(owner, key, value)
        names = ", ".join(r["name"] for r in rows)
        # (issue #63: the look changed without a word)
        look = f"; its look too: {', '.join(changed)} (With Its Look off: the species alone)" if changed else ""
        self.report({"INFO"}, f"Species of '{item.name}': {names}{look}")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_species_preset,)
