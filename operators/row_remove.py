"""windgrass.row_remove: remove the selected row of a table parameter (grass species, wind keys)."""

import bpy

from ..grass_addon.bridge.runtime import properties
from ._common import active_field, has_active_field, reported


class WINDGRASS_OT_row_remove(bpy.types.Operator):
    """Remove the selected row of a table of the active field (a species, a wind key)"""

    bl_idname = "windgrass.row_remove"
    bl_label = "Remove Row"
    bl_description = "Remove the selected row of a table of the active field (a grass species, a wind key)"
    bl_options = {"REGISTER", "UNDO"}

    table: bpy.props.StringProperty(name="Table", default="blade.species", options={"HIDDEN", "SKIP_SAVE"},
                                    description="Table parameter to remove a row from (blade.species, wind.keys)")

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = active_field(context.scene)
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


CLASSES = (WINDGRASS_OT_row_remove,)
