"""Blender side of Windgrass (may import bpy): properties, scene objects, materials, runtime.

Submodules are imported where they are used, so that one half-finished module never stops the
others from loading.
"""
