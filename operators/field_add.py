"""windgrass.field_add: add a grass field (Add menu: "Grass Field", and "Grass Field on Selected
Mesh", which roots it on the selected mesh; the panel's + button adds one on flat ground)."""

import math

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import FieldGrid, WindgrassError, maps, presets, properties, schema
from ._common import refresh, reported

# First click: a light field for interactive use, 8 x 8 blocks of 16 x 16 cells of 0.1 m
# (12.8 m square, 32,768 blades), a meadow (presets.py: its species, tussocks, patches and dry
# tips, an edge that thins out) in a breeze whose gust waves run over it; every other value is the
# schema default.
FIRST_CLICK = {"blocks_x": 8, "blocks_y": 8, "edge": 0.8,  # (its edge thins out: no wall seen from outside)
               **{k.split(".")[1]: v for k, v in presets.LOOKS["meadow"].items() if k.startswith("field.")}}
FIRST_LOOK = "meadow"
FIRST_GUST_WAVES = 0.3
# On a terrain the field fits the mesh's XY extent (cell size kept) unless blocks_x/blocks_y are
# given, up to this many blocks (a light field; the artist can grow it in the panel).
FIT_MAX_BLOCKS = 256


def _field_options() -> dict:
    """One operator option per [field] parameter and view (size, blades per m²), generated from the
    schema; a view given wins over the parameters it sets."""
    first = schema.defaults().replace({f"field.{k}": v for k, v in FIRST_CLICK.items()}).to_dict()["field"]
    views = {v.param.key: properties.make_property(v.param, default=v.read(first), update=None, animatable=False,
                                                   skip_save=True)  # (a size once typed is not the next Add's)
             for v in schema.section_views("field")}
    return {**views, **{p.key: properties.make_property(p, default=FIRST_CLICK.get(p.key), update=None,
                                                        animatable=False)
                        for p in schema.section_params("field")}}


class WINDGRASS_OT_field_add(bpy.types.Operator):
    """Add a grass field swaying in the wind, on flat ground or rooted on the selected mesh"""

    bl_idname = "windgrass.field_add"
    bl_label = "Add Grass Field"
    bl_description = "Add a grass field with three levels of detail that sways in a physical wind"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = {
        **_field_options(),
        "use_selected_mesh": bpy.props.BoolProperty(
            name="On Selected Mesh", default=False, options={"SKIP_SAVE"},  # (each menu entry says which)
            description="Root the blades on the surface of the selected mesh (its terrain): the field is "
                        "centred on the mesh and sized to it unless Blocks X/Y are set. Off: flat ground"),
    }

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "windgrass")

    def invoke(self, context, event):
        """From the Add menu (or F3): the field's engine is made in the background, so the window
        is not held while it is (its first look shows once the blocks are made)."""
        self.in_background = not bpy.app.background
        return self.execute(context)

    @reported
    def execute(self, context):
        scene = context.scene
        terrain = self._terrain(context) if self.use_selected_mesh else None
        values = {p.key: getattr(self, p.key) for p in schema.section_params("field")}
        for view in schema.section_views("field"):  # (the redo panel's Size X/Y and Blades)
            if self.properties.is_property_set(view.param.key):
                values.update(view.write(values, getattr(self, view.param.key)))
        uncovered = None
        if terrain is not None:
            fit, uncovered = self._fit_to(terrain, values)
            values.update(fit)
        # a meadow: the preset's species and look, then the field's settings as given here
        params = presets.apply_preset(schema.defaults(), FIRST_LOOK).replace(
            {"wind.gust_waves": FIRST_GUST_WAVES, **{f"field.{k}": v for k, v in values.items()}})
        item = properties.add_field(scene, params)
        if terrain is not None:
            item.terrain = terrain
        locked = scene.render.use_lock_interface
        try:
            later = getattr(self, "in_background", False)
            collection = (runtime.build_in_background if later else runtime.build_field)(scene, item)
        except Exception:  # whatever stopped the build, the half-added field goes before it is raised
            _undo_add(scene, item)
            raise
        if collection is not None and item.collection is None:
            item.collection = collection
        if not later:  # (a frame written now would wait for the field's engine)
            refresh(scene)
        grid = FieldGrid.of(params)
        blades, (size_x, size_y) = grid.n_blades, grid.size
        where = f" rooted on '{terrain.name}'" if terrain is not None else ""
        error = runtime.field_error(scene, item)
        if error:  # (its objects are made: the undo step holds them; the panel says why it is hidden)
            self.report({"ERROR"}, f"Added grass field '{item.name}', but its grass is hidden: {error}")
            return {"FINISHED"}
        # (issue #63: the add-on turned Render > Lock Interface on without a word)
        lock = "; Render > Lock Interface turned on (the grass is written while a frame renders)" \
            if scene.render.use_lock_interface and not locked else ""
        self.report({"INFO"}, f"Added grass field '{item.name}': {blades:,} blades on {size_x:g} x {size_y:g} m{where}"
                              f"{lock}")
        if uncovered:
            self.report({"WARNING"}, uncovered)
        return {"FINISHED"}


    @staticmethod
    def _terrain(context):
        """The selected mesh to grow on; WindgrassError when there is none (never a grass field's
        own object: its ground is no terrain)."""
        obj = context.active_object
        if obj is None or not obj.select_get() or obj.type != "MESH":
            raise WindgrassError("Grass Field on Selected Mesh: select the mesh to grow the grass on first "
                                 "(or add a field on flat ground)")
        if obj.get("wg_uid") is not None or obj.get("wg_role") is not None:
            raise WindgrassError(f"Grass Field on Selected Mesh: '{obj.name}' belongs to a grass field; select "
                                 "a mesh of your own to grow the grass on")
        return obj

    def draw(self, context):
        """The redo panel: what an artist decides (size, density, seed); the blocks and cells that
        give them are the field's Advanced settings."""
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        for key in [v.param.key for v in schema.section_views("field")] + ["seed", "use_selected_mesh"]:
            layout.prop(self, key)

    def _fit_to(self, terrain, values: dict) -> tuple[dict, str | None]:
        """blocks_x/blocks_y (and, past FIT_MAX_BLOCKS, larger blocks: more cells a block, the cell
        size and the density kept) covering the terrain's XY extent (world bounding box) when not
        given, and a sentence when even the largest blocks leave part of it bare (else None)."""
        given = ("blocks_x", "blocks_y", "size_x", "size_y")
        if any(self.properties.is_property_set(key) for key in given):
            return {}, None
        extent = maps.extent_xy(terrain)
        cells, size = values["cells_per_block"], values["cell_size"]
        most_cells = int(schema.BY_NAME["field.cells_per_block"].soft_max or cells)  # (larger: cards too heavy)
        if not self.properties.is_property_set("cells_per_block"):
            while cells < most_cells and math.prod(FieldGrid.blocks_covering(extent, cells * size, 10**9)) \
                    > FIT_MAX_BLOCKS:
                cells += 1
        bx, by = FieldGrid.blocks_covering(extent, cells * size, FIT_MAX_BLOCKS)
        covered = (bx * cells * size, by * cells * size)
        if covered[0] < extent[0] - 1e-6 or covered[1] < extent[1] - 1e-6:
            note = (f"The field covers {covered[0]:g} x {covered[1]:g} m of the {extent[0]:.4g} x {extent[1]:.4g} m "
                    f"mesh (at most {FIT_MAX_BLOCKS} blocks of {cells * size:g} m are added at once): raise Size X/Y "
                    "in the panel to cover the rest")
        else:
            note = None
        return {"blocks_x": bx, "blocks_y": by, "cells_per_block": cells}, note


def _undo_add(scene, item) -> None:
    """A failed build leaves neither objects nor a settings item."""
    try:
        runtime.remove_field(scene, item)
    finally:
        properties.remove_item(scene, item)


def menu_func(self, context):
    self.layout.operator(WINDGRASS_OT_field_add.bl_idname, text="Grass Field", icon="OUTLINER_OB_CURVES")
    self.layout.operator(WINDGRASS_OT_field_add.bl_idname, text="Grass Field on Selected Mesh",
                         icon="OUTLINER_OB_CURVES").use_selected_mesh = True


# Add menu (Shift+A) of the 3D View, next to the other object types.
MENUS = ("VIEW3D_MT_add",)
CLASSES = (WINDGRASS_OT_field_add,)
