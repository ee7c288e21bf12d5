"""Blender tests: every test starts from factory settings with the add-on loaded and registered.

``tests/conftest.py`` points Blender's user files at a temp dir before this imports bpy.
"""

import importlib

import bpy
import pytest
from addon_loader import load_addon


@pytest.fixture(autouse=True)
def addon():
    """Factory settings (empty scene) and the registered add-on package ``windgrass``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    module = load_addon()
    if not hasattr(bpy.types.Scene, "windgrass"):  # something unregistered it behind our back
        module.unregister()
        module.register()
    yield module


@pytest.fixture
def scene():
    return bpy.context.scene


@pytest.fixture
def with_bridge(addon):
    """The add-on with its engine facade and bridge imported (an import error fails the test)."""
    for name in ("field", "bridge.scene", "bridge.runtime"):
        importlib.import_module(f"{addon.__name__}.grass_addon.{name}")
    return addon
