"""Sidebar panels of the 3D View, tab "Grass"."""

import bpy

from . import main, sections

CLASSES = (*main.CLASSES, *sections.CLASSES)


def register() -> None:
    for cls in CLASSES:
        if not getattr(cls, "is_registered", False):
            bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
