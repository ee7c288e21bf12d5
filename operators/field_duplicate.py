"""windgrass.field_duplicate: a working copy of the active field (what Shift+D on its objects
cannot give: a copied object is no field)."""

import bpy

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import owned, properties
from ._common import active_field, has_active_field, refresh, reported


class WINDGRASS_OT_field_duplicate(bpy.types.Operator):
    """Duplicate the active grass field: a new field with the same settings, beside it"""

    bl_idname = "windgrass.field_duplicate"
    bl_label = "Duplicate Field"
    bl_description = ("Add a grass field with the active field's settings, terrain, paint and collections, beside "
                      "it along X (on a terrain: on a linked copy of the terrain beside it; a copy of its objects with "
                      "Shift+D is not a field)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return has_active_field(context)

    @reported
    def execute(self, context):
        scene = context.scene
        source = active_field(scene)
        params = properties.params_from_settings(source)  # (a bad setting stops here, named)
        inputs = {key: getattr(source, key) for key in INPUTS}
        name, uid = source.name, source.uid
        item = properties.add_field(scene, params, name=name)
        # Adding to the fields collection may move its items: ``source`` is dead now, look it up again.
        source = properties.field_by_uid(scene, uid)
        terrain = inputs["terrain"]
        if terrain is not None:
            inputs["terrain"] = _terrain_beside(context, terrain)
        for key, value in inputs.items():
            setattr(item, key, value)
        if terrain is not None:
            item[runtime.TERRAIN_COPY_KEY] = inputs["terrain"]  # (Remove Field deletes it with the field)
        runtime.build_field(scene, item)
        ground, original = owned.ground_object(item), owned.ground_object(source)
        if ground is not None and original is not None and item.terrain is None:
            ground.matrix_basis = original.matrix_basis.copy()
            ground.location.x += 1.1 * ground.dimensions.x  # beside it, not on top
        refresh(scene)
        self.report({"INFO"}, f"Duplicated grass field '{name}' as '{item.name}'")
        return {"FINISHED"}


# What a field takes from the scene besides its settings: the copy takes the same.
INPUTS = ("terrain", "collider_collection", "effector_collection", "keep_out_collection")


def _terrain_beside(context, terrain):
    """A linked copy of ``terrain`` (the same mesh) beside it along X, in the terrain's collections:
    a field on a terrain is centred on it, so the copy's field stands beside the original's."""
    copy = terrain.copy()
    for collection in terrain.users_collection or (context.scene.collection,):
        collection.objects.link(copy)
    copy.location.x += 1.1 * terrain.dimensions.x
    return copy


CLASSES = (WINDGRASS_OT_field_duplicate,)
