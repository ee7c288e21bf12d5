"""Operators, one per file, all in the ``windgrass.`` namespace (F3: search "Grass")."""

import bpy

from . import (
    farm_job,
    field_add,
    field_bake,
    field_bake_free,
    field_duplicate,
    field_map_add,
    field_rebuild,
    field_remove,
    map_pick,
    row_add,
    row_remove,
    simulation_reset,
    species_preset,
    track_update,
    wind_force_add,
    wind_preset,
)

_MODULES = (field_add, field_rebuild, field_remove, field_bake, field_bake_free, simulation_reset, wind_preset,
            species_preset, row_add, row_remove, map_pick, track_update, farm_job, field_duplicate,
            wind_force_add, field_map_add)
CLASSES = tuple(cls for module in _MODULES for cls in module.CLASSES)


def register() -> None:
    for cls in CLASSES:
        if not cls.is_registered:
            bpy.utils.register_class(cls)
    for menu in field_add.MENUS:
        getattr(bpy.types, menu).remove(field_add.menu_func)  # never twice in the menu
        getattr(bpy.types, menu).append(field_add.menu_func)


def unregister() -> None:
    for menu in field_add.MENUS:
        getattr(bpy.types, menu).remove(field_add.menu_func)
    for cls in reversed(CLASSES):
        if cls.is_registered:
            bpy.utils.unregister_class(cls)
