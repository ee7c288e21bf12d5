"""The "Grass" tab of the 3D View sidebar: the list of fields and their main buttons."""

import textwrap

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import FieldGrid, owned, properties

CATEGORY = "Grass"
CHAR_PX = 7.0  # width of an average character of the interface font at scale 1 (pixels)


def wrapped(layout, context, text: str, icon: str = "NONE", inset: float = 0.0) -> None:
    """``text`` as labels that fit the region's width (the sidebar can be narrow): the first line
    with ``icon``, the rest below it; ``inset``: UI units (20 px) of the width the layout's boxes
    take (a table's box: its text was cut, "No keys: Changes of the mean win...")."""
    region = getattr(context, "region", None)
    scale = context.preferences.view.ui_scale if context.preferences is not None else 1.0
    width = (region.width if region is not None else 300) - inset * 20.0 * scale
    indent = 2 if icon != "NONE" else 0
    chars = max(16, int(width / (CHAR_PX * scale)) - 4 - indent)
    col = layout.column(align=True)
    for i, line in enumerate(textwrap.wrap(text, chars) or [""]):
        col.label(text=line, icon=icon if i == 0 else "BLANK1" if icon != "NONE" else "NONE")


def length_text(scene, metres: float) -> str:
    """A length as the scene's unit system writes it (3.2 m, 10' 6", or a plain number)."""
    units = scene.unit_settings
    if units.system == "NONE":
        return f"{metres:.4g}"
    return bpy.utils.units.to_string(units.system, "LENGTH", metres * units.scale_length, precision=3)


# Row PropertyGroup name -> its table parameter (the columns come from the schema).
_ROW_TABLES = {cls.__name__: properties.table_param(name) for name, cls in properties.ROW_CLASSES.items()}


class WINDGRASS_UL_fields(bpy.types.UIList):
    """The scene's grass fields."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.prop(item, "name", text="", emboss=False, icon="OUTLINER_OB_CURVES")
        if runtime.field_error(context.scene, item):
            row.label(text="", icon="ERROR")  # a setting cannot be simulated: see the panel
        elif item.collection is not None:
            row.label(text="", icon="OUTLINER_COLLECTION")
        else:
            row.label(text="", icon="ERROR")  # settings without objects: press Rebuild


class WINDGRASS_UL_rows(bpy.types.UIList):
    """Rows of a table parameter (species, wind keys): its first columns, colour as a swatch."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        table = _ROW_TABLES.get(item.bl_rna.identifier)
        keys = [f.key for f in table.fields] if table is not None else []
        if "color" in keys:
            sub = row.row()
            sub.ui_units_x = 1.2
            sub.prop(item, "color", text="")
        # a named row shows its name (a species), others their first two numbers (a wind key's time,
        # speed): more would be cut at the sidebar's width
        shown = ["name"] if "name" in keys else [k for k in keys if k != "color"][:2]
        for key in shown:
            row.prop(item, key, text="", emboss=key != "name")


class WINDGRASS_PT_main(bpy.types.Panel):
    bl_label = "Windgrass"
    bl_idname = "WINDGRASS_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = CATEGORY

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "windgrass")

    def draw(self, context):
        layout = self.layout
        root = context.scene.windgrass
        if not len(root.fields):
            layout.operator("windgrass.field_add", icon="ADD")
            return
        row = layout.row()
        row.template_list("WINDGRASS_UL_fields", "", root, "fields", root, "active_index", rows=3)
        col = row.column(align=True)
        col.operator("windgrass.field_add", text="", icon="ADD")
        col.operator("windgrass.field_remove", text="", icon="REMOVE")
        col.separator()
        col.operator("windgrass.field_duplicate", text="", icon="DUPLICATE")
        row = layout.row(align=True)
        row.operator("windgrass.field_rebuild", text="Rebuild", icon="FILE_REFRESH")
        row.operator("windgrass.simulation_reset", text="Reset", icon="LOOP_BACK")
        for note in owned.orphan_notes(context.scene):
            wrapped(layout, context, note, icon="INFO")
        item = properties.active_field(context.scene)
        if item is not None:
            error = runtime.field_error(context.scene, item)
            if error:
                box = layout.box()
                box.alert = True
                wrapped(box, context, "Grass hidden: this field cannot be simulated", icon="ERROR")
                wrapped(box, context, error)
            working = runtime.background_work(context.scene, item)
            if working is not None:
                wrapped(layout, context, working, icon="SORTTIME")
            f = item.field
            grid = FieldGrid(f.blocks_x, f.blocks_y, f.cells_per_block, f.cell_size, f.blades_per_cell)
            size_x, size_y = (length_text(context.scene, v) for v in grid.size)
            painted = item.paint.density or any(s.density_map for s in item.blade.species)
            count = f"up to {grid.n_blades:,} blades (the painted density decides)" if painted \
                else f"{grid.n_blades:,} blades"
            wrapped(layout, context, f"{size_x} x {size_y}, {count}", icon="INFO")
            col = layout.column()
            col.use_property_split = True
            col.use_property_decorate = False
            col.prop(item, "collection")
            col.prop(item, "terrain")  # a mesh to root the blades on; Rebuild re-samples it


CLASSES = (WINDGRASS_UL_fields, WINDGRASS_UL_rows, WINDGRASS_PT_main)
