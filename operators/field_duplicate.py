"""windgrass.field_duplicate: a working copy of the active field (what Shift+D on its objects
cannot give: a copied object is no field)."""

import bpy

from ..grass_addon.bridge import owned, properties, runtime
from ._common import has_active_field, refresh, reported


class WINDGRASS_OT_field_duplicate(bpy.types.Operator):
    """Duplicate the active grass field: a new field with the same settings, beside it"""

    bl_idname = "windgrass.field_duplicate"
    bl_label = "Duplicate Field"
    bl_description = ("Add a grass field with the active field's settings, terrain, paint and collections, beside "
                      "it along X (a copy of its objects with Shift+D is not a field)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        source = properties.active_field(scene)
        params = properties.params_from_settings(source)  # (a bad setting stops here, named)
        item = properties.add_field(scene, params, name=source.name)
        for key in ("terrain", "collider_collection", "effector_collection", "keep_out_collection"):
            if hasattr(source, key):
                setattr(item, key, getattr(source, key))
        runtime.build_field(scene, item)
        ground, original = owned.ground_object(item), owned.ground_object(source)
        if ground is not None and original is not None and item.terrain is None:
            ground.matrix_basis = original.matrix_basis.copy()
            ground.location.x += 1.1 * ground.dimensions.x  # beside it, not on top
        refresh(scene)
        self.report({"INFO"}, f"Duplicated grass field '{source.name}' as '{item.name}'")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_field_duplicate,)
