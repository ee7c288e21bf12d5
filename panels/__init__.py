"""Sidebar panels of the 3D View, tab "Grass"."""

import bpy

from . import main, sections

CLASSES = (*main.CLASSES, *sections.CLASSES)


def register() -> None:
    for cls in CLASSES:
        if not cls.is_registered:
            bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        if cls.is_registered:
            bpy.utils.unregister_class(cls)
