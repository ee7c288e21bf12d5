"""windgrass.species_remove: remove the selected row of the species list (or another table)."""

import bpy

from ..grass_addon.bridge import properties
from ._common import has_active_field, reported


class WINDGRASS_OT_species_remove(bpy.types.Operator):
    """Remove the selected grass species from the active field"""

    bl_idname = "windgrass.species_remove"
    bl_label = "Remove Grass Species"
    bl_description = "Remove the selected grass species from the active field"
    bl_options = {"REGISTER", "UNDO"}

    table: bpy.props.StringProperty(name="Table", default="blade.species", options={"HIDDEN", "SKIP_SAVE"},
                                    description="Table parameter to remove a row from (blade.species, wind.keys)")

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = properties.active_field(context.scene)
        p, group, rows, index_name = properties.table_rows(item, self.table)
        if not len(rows):
            self.report({"WARNING"}, f"{p.name} of '{item.name}' has no rows to remove")
            return {"CANCELLED"}
        index = min(getattr(group, index_name), len(rows) - 1)
        with properties.batch(item):  # removing a row fires no update callback: notify at the end
            rows.remove(index)
            setattr(group, index_name, max(0, min(index, len(rows) - 1)))
        self.report({"INFO"}, f"Removed row {index + 1} of {p.name} of '{item.name}'")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_species_remove,)
