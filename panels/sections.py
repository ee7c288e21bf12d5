"""One sidebar sub-panel per schema section, drawn from ``schema.section_params`` so that a new
parameter shows up without touching this file."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import WindgrassError, maps, properties, schema, seek_note, tracks
from .main import CATEGORY, WINDGRASS_PT_main, wrapped

LABELS = {
    "field": "Field",
    "terrain": "Terrain from a Heightmap",
    "paint": "Paint",
    "keep_out": "Keep Out",
    "interaction": "Colliders & Force Fields",
    "blade": "Blades & Species",
    "wind": "Wind",
    "lod": "Levels of Detail",
    "camera": "Headless Camera",
    "render": "Headless Render",
    "simulation": "Simulation",
}
# Sections only used by headless renders (headless/render_field.py) start closed.
HEADLESS = frozenset({"camera", "render", "terrain"})
# A section's on/off switch, drawn in its header as Blender's own panels do (Motion Blur, Bloom):
# the body is greyed out while it is off.
HEADER_SWITCH = {"lod": "enabled"}
# Preset operators drawn on top of a section: (operator, its enum property, button text).
PRESETS = {
    "blade": ("windgrass.species_preset", "preset", "Species Preset"),
    "wind": ("windgrass.wind_preset", "type", "Wind Preset"),
}


SUFFIX_CHARS = 2  # units up to this long are written after the value (MB); longer ones (kg/m) in the tooltip


COLLECTION_FIELDS = frozenset({"plant"})  # table columns that name one of the file's collections


def draw_table(layout, context, group, p: schema.Param) -> None:
    """UI list of a table parameter, add/remove buttons and the selected row's columns."""
    box = layout.box()
    box.label(text=p.ui_name)
    row = box.row()
    index = properties.index_name(p)
    row.template_list("WINDGRASS_UL_rows", p.name, group, p.key, group, index, rows=3)
    col = row.column(align=True)
    col.operator("windgrass.row_add", text="", icon="ADD").table = p.name
    col.operator("windgrass.row_remove", text="", icon="REMOVE").table = p.name
    rows = getattr(group, p.key)
    if not len(rows):
        wrapped(box, context, f"No {p.ui_name.lower()}: {p.help}", icon="INFO", inset=2.0)
        return
    chosen = min(getattr(group, index), len(rows) - 1)
    selected = rows[chosen]
    col = box.column()
    for f in p.fields:
        if f.key in COLLECTION_FIELDS:  # a collection of this file, found by name
            col.prop_search(selected, f.key, bpy.data, "collections", text=f.ui_name, icon="OUTLINER_COLLECTION")
        elif f.path:
            draw_map(col, selected, f.key, f"{p.name}[{chosen}].{f.key}")
        else:
            draw_value(col, selected, f)


def draw_map(layout, owner, key: str, setting: str) -> None:
    """A map setting: its label, then its text (a file, or vertex_group:/attribute:/image: NAME) the
    sidebar's whole width (a map's name is long) with a button that lists what the terrain and
    the file offer."""
    col = layout.column(align=True)
    col.use_property_split = False
    col.label(text=owner.bl_rna.properties[key].name)
    row = col.row(align=True)
    row.prop(owner, key, text="")
    row.operator("windgrass.map_pick", text="", icon="GROUP_VERTEX").setting = setting


def draw_value(layout, owner, p: schema.Param) -> None:
    """One setting: its label and value, the unit after it where Blender cannot show it (kg/m,
    MB), a vector's numbers each with its own label (an extent's Min X ... Max Y)."""
    if p.components:
        col = layout.column(align=True)
        for i, name in enumerate(p.components):
            col.prop(owner, p.key, index=i, text=f"{p.ui_name} {name}" if i == 0 else name)
        return
    unit = properties.unit_suffix(p)
    if not unit or len(unit) > SUFFIX_CHARS:  # (a long unit would cut the label: the tooltip gives it)
        layout.prop(owner, p.key)
        return
    row = layout.row(align=True)
    row.prop(owner, p.key)
    sub = row.row()
    sub.ui_units_x = max(1.5, 0.42 * len(unit))
    sub.label(text=unit)


def draw_params(layout, context, group, params) -> None:
    layout.use_property_split = True
    layout.use_property_decorate = True  # keyframe dots on the animatable ones (wind speed, direction)
    for p in params:
        if p.applies_when and getattr(group, p.applies_when[0]) != p.applies_when[1]:
            continue  # e.g. the gust front's settings while the wind is not a blast
        if p.kind == "table_list":
            draw_table(layout, context, group, p)
        elif p.path and p.section == "paint":
            draw_map(layout, group, p.key, p.name)
        else:
            draw_value(layout, group, p)


def draw_section(layout, context, item, section: str) -> None:
    """What an artist decides first (the section's views, then its settings but the advanced
    ones, which ``_advanced_panel`` draws) and the section's notes."""
    group = properties.group(item, section)
    if section in PRESETS:
        op, prop, text = PRESETS[section]
        layout.operator_menu_enum(op, prop, text=text, icon="PRESET")
    views = [v.param for v in schema.section_views(section)]
    switch = HEADER_SWITCH.get(section)
    if switch:
        layout.active = bool(getattr(group, switch))
    draw_params(layout, context, group, views + [p for p in schema.blender_params(section)
                                                 if not p.advanced and p.key != switch])
    if section == "field":
        try:
            f = properties.params_from_settings(item).field
        except WindgrassError:
            f = None  # (a setting out of range: the main panel says which)
        if f is not None:
            block = f.cells_per_block * f.cell_size
            wrapped(layout, context, f"Sizes round to whole blocks of {block:g} m, densities to whole blades per "
                    f"{f.cell_size:g} m cell (Advanced)", icon="INFO")
    if section == "lod":
        drawn = runtime.blades_drawn(context.scene, item)
        if drawn is not None:
            amount = item.lod.viewport_amount
            wrapped(layout, context, f"Drawn now: {drawn:,} blades" + (
                f" ({amount:.0%} in the viewport; renders draw every blade)" if amount < 1.0 else ""), icon="INFO")
    if section == "wind":
        if runtime.wind_force.available():
            layout.operator("windgrass.wind_force_add", icon="FORCE_WIND")
            if runtime.wind_force.map_object(item) is not None:
                wrapped(layout, context, f"Hair Dynamics and Cloth Dynamics blow in this wind with the collection "
                        f"'{runtime.wind_force.COLLECTION}' as their Effectors Collection", icon="INFO")
        else:
            wrapped(layout, context, runtime.wind_force.needs_note(), icon="INFO")
        layout.operator("windgrass.field_map_add", icon="GEOMETRY_NODES")
        shared = runtime.wind_force.map_object(item)
        if shared is not None:
            wrapped(layout, context, f"Node trees read this field from '{shared.name}' (Object Info)", icon="INFO")
    if section == "keep_out":
        layout.prop(item, "keep_out_collection")
        for line in maps.keep_out_notes(item):
            wrapped(layout, context, line, icon="INFO")
    if section == "interaction":
        layout.prop(item, "collider_collection")
        layout.prop(item, "effector_collection")
        layout.operator("windgrass.track_update", icon="FILE_REFRESH")
        note: str | None = None
        try:
            note = tracks.status(context.scene, item, properties.params_from_settings(item, context.scene))
        except WindgrassError:
            pass
        for line in ([note] if note else []) + tracks.notes(item):
            wrapped(layout, context, line, icon="INFO")
    if section == "paint":
        seconds = runtime.stroke_seconds(context.scene, item)
        if seconds > runtime.STROKE_GOAL_S:
            wrapped(layout, context, f"A stroke takes {seconds:.1f} s to show on this field: the grass follows "
                    "when you leave paint mode (or change frame)", icon="TIME")
    if section == "simulation":
        clock = runtime.scene_clock(context.scene)
        wrapped(layout, context, f"Steps at the scene's {clock.rate:.4g} fps from frame {clock.frame_start}",
                icon="INFO")
        try:
            note = seek_note(properties.params_from_settings(item, context.scene))
        except WindgrassError:
            note = None  # a setting out of range: the main panel says which
        if note:
            wrapped(layout, context, note[0].upper() + note[1:], icon="TIME")
        if item.simulation.loop > 0.0:
            wrapped(layout, context, f"Every blade repeats after {item.simulation.loop:g} s: render or bake one "
                    "loop and play it in a cycle", icon="LOOP_FORWARDS")
        for note in runtime.loop_notes(context.scene, item):  # (what breaks the loop)
            wrapped(layout, context, "The loop has a seam: " + note, icon="ERROR")


def _panel_type(idname: str, label: str, parent: str, closed: bool, draw, **more) -> type:
    """A sub-panel of the Grass tab shown while a field is selected (``more``: e.g. its
    ``draw_header``)."""
    return type(idname, (bpy.types.Panel,), {**more,
        "bl_label": label,
        "bl_idname": idname,
        "bl_space_type": "VIEW_3D",
        "bl_region_type": "UI",
        "bl_category": CATEGORY,
        "bl_parent_id": parent,
        "bl_options": {"DEFAULT_CLOSED"} if closed else set(),
        "poll": classmethod(lambda cls, context: context.scene is not None
                            and properties.active_field(context.scene) is not None),
        "draw": draw,
    })


def _panel(section: str) -> type:
    def draw(self, context):
        draw_section(self.layout, context, properties.active_field(context.scene), section)

    more = {}
    if section in HEADER_SWITCH:
        def draw_header(self, context):
            group = properties.group(properties.active_field(context.scene), section)
            self.layout.prop(group, HEADER_SWITCH[section], text="")

        more["draw_header"] = draw_header
    parent = BATCH_PANEL if section in HEADLESS else WINDGRASS_PT_main.bl_idname
    return _panel_type(f"WINDGRASS_PT_{section}", LABELS.get(section, section.capitalize()), parent,
                       section in HEADLESS, draw, **more)


def _advanced_panel(section: str) -> type:
    """The section's physical parameters, collapsed (as Blender's cloth and hair panels do)."""

    def draw(self, context):
        params = [p for p in schema.blender_params(section) if p.advanced]
        draw_params(self.layout, context, properties.group(properties.active_field(context.scene), section), params)

    return _panel_type(f"WINDGRASS_PT_{section}_advanced", "Advanced", f"WINDGRASS_PT_{section}", True, draw)


BATCH_PANEL = "WINDGRASS_PT_batch"


def _batch_panel() -> type:
    """The settings only batch renders use (camera, render, a heightmap terrain), together in one
    closed panel below the artist's own."""

    def draw(self, context):
        wrapped(self.layout, context, "Used by batch renders (headless/render_field.py); in Blender the scene's "
                "camera, frame rate and frame range rule, and a terrain mesh roots the grass", icon="INFO")

    return _panel_type(BATCH_PANEL, "Batch Renders", WINDGRASS_PT_main.bl_idname, True, draw)


def _bake_panel() -> type:
    """Bake, Free Bake and Farm Job at the bottom of the tab, where Blender's physics panels keep
    their cache and bake."""

    def draw(self, context):
        item = properties.active_field(context.scene)
        layout = self.layout
        row = layout.row(align=True)
        row.operator_menu_enum("windgrass.field_bake", "format", text="Bake", icon="FILE_CACHE")
        row.operator("windgrass.field_bake_free", text="Free Bake", icon="TRASH")
        layout.operator("windgrass.farm_job", icon="NETWORK_DRIVE")
        status = runtime.bake_status(context.scene, item)
        if status:
            box = layout.box()
            box.alert = "stale" in status
            wrapped(box, context, status)

    return _panel_type("WINDGRASS_PT_bake", "Bake & Farm", WINDGRASS_PT_main.bl_idname, False, draw)


ADVANCED = tuple(s for s in schema.SECTIONS if any(p.advanced for p in schema.blender_params(s)))
ORDER = [s for s in schema.SECTIONS if s not in HEADLESS]  # (the artist's sections, then the batch renders')
CLASSES = (tuple(_panel(s) for s in ORDER) + tuple(_advanced_panel(s) for s in ADVANCED if s not in HEADLESS)
           + (_batch_panel(),) + tuple(_panel(s) for s in schema.SECTIONS if s in HEADLESS)
           + tuple(_advanced_panel(s) for s in ADVANCED if s in HEADLESS) + (_bake_panel(),))
