"""windgrass.row_add: add a row to a table parameter (grass species, wind keys)."""

import bpy

from ..grass_addon.bridge.runtime import properties, schema
from ._common import active_field, has_active_field, reported

# Rows of a table with a "time" column must have strictly increasing times (schema relation);
# a new row goes this many seconds after the last one.
TIME_STEP = 1.0


class WINDGRASS_OT_row_add(bpy.types.Operator):
    """Add a row to a table of the active field (a species, a wind key): a copy of the selected one"""

    bl_idname = "windgrass.row_add"
    bl_label = "Add Row"
    bl_description = ("Add a row to a table of the active field (a grass species, a wind key), copying the "
                      "selected one; a wind key goes one second after the last")
    bl_options = {"REGISTER", "UNDO"}

    table: bpy.props.StringProperty(name="Table", default="blade.species", options={"HIDDEN", "SKIP_SAVE"},
                                    description="Table parameter to add a row to (blade.species, wind.keys)")

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        item = active_field(context.scene)
        p, group, rows, index_name = properties.table_rows(item, self.table)
        if len(rows):
            source = rows[min(getattr(group, index_name), len(rows) - 1)]
            values = {f.key: properties.from_blender(f, getattr(source, f.key)) for f in p.fields}
            if "time" in values:  # after the last key, so times keep increasing
                last = rows[len(rows) - 1]
                time = next(f for f in p.fields if f.key == "time")
                values["time"] = properties.from_blender(time, last.time) + TIME_STEP
        else:
            values = schema.row_defaults(p.fields)
        with properties.batch(item):  # one runtime update for the whole row
            row = rows.add()
            for f in p.fields:
                setattr(row, f.key, properties.to_blender(f, values[f.key]))
            setattr(group, index_name, len(rows) - 1)
        self.report({"INFO"}, f"Added row {len(rows)} to {p.name} of '{item.name}'")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_row_add,)
