"""windgrass.map_pick: choose what a map setting reads (a vertex group, attribute or image of the
terrain, an image of the file), from a searchable list of what there is."""

import bpy

from ..grass_addon.bridge.runtime import maps, properties
from ._common import has_active_field, reported

NONE = "NONE"


_SOURCES_KEPT: list[tuple[str, str, str]] = []


def _sources(self, context):
    """(value, label, description) of every source the active field's map can read now."""
    items = [(NONE, "None", "No map: grass everywhere, as grown")]
    scene = context.scene
    item = properties.active_field(scene) if scene is not None else None
    terrain = maps.terrain_object(scene, item) if item is not None else None
    if terrain is not None:
        items += [(f"vertex_group:{g.name}", f"Vertex Group: {g.name}", f"Weights of '{terrain.name}' (Weight Paint)")
                  for g in terrain.vertex_groups]
        items += [(f"attribute:{a.name}", f"Attribute: {a.name}", f"Values of '{terrain.name}' (Vertex Paint)")
                  for a in terrain.data.attributes
                  if a.data_type in ("FLOAT", "FLOAT_COLOR", "BYTE_COLOR") and a.domain in ("POINT", "CORNER")
                  and not a.name.startswith(".")]
    where = f"over the UV map of '{terrain.name}'" if terrain is not None else "over the field"
    items += [(f"image:{i.name}", f"Image: {i.name}", f"Grey levels of the image {where} (Texture Paint)")
              for i in bpy.data.images if i.type in ("IMAGE", "UV_TEST") and not i.get("wg_uid")]
    _SOURCES_KEPT[:] = items  # (Blender keeps the strings only while a reference lives)
    return _SOURCES_KEPT


class WINDGRASS_OT_map_pick(bpy.types.Operator):
    """Choose what this map reads: a vertex group or attribute of the terrain, or an image"""

    bl_idname = "windgrass.map_pick"
    bl_label = "Choose Map"
    bl_description = ("Choose what this map reads: a vertex group or attribute of the terrain mesh (paint it in "
                      "Weight or Vertex Paint), or an image (Texture Paint)")
    bl_options = {"REGISTER", "UNDO"}
    bl_property = "source"

    setting: bpy.props.StringProperty(
        name="Setting", options={"HIDDEN", "SKIP_SAVE"},
        description="The map setting to set (paint.density, blade.species[0].density_map)")
    source: bpy.props.EnumProperty(name="Source", items=_sources)

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    def invoke(self, context, event):
        context.window_manager.invoke_search_popup(self)
        return {"RUNNING_MODAL"}

    @reported
    def execute(self, context):
        item = properties.active_field(context.scene)
        owner, key = properties.map_owner(item, self.setting)
        setattr(owner, key, "" if self.source == NONE else self.source)
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_map_pick,)
