"""The repository as the package ``windgrass``: the one name every script and test imports it by.

The repository root is the extension; its package name is the manifest id, ``windgrass`` (Blender
itself imports an installed copy as ``bl_ext.<repository>.windgrass``). Inside the extension all
imports are relative, so the name only appears here. ``load_package`` makes ``windgrass`` and its
engine ``windgrass.grass_addon`` importable without Blender (the numpy core never imports bpy);
``load_addon`` also registers the add-on with Blender. Importing the engine by any other name
(``grass_addon`` with the repository on ``sys.path``) would load a second copy of every module.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parent.parent
PACKAGE = "windgrass"


def load_package() -> ModuleType:
    """Import the repository root as package ``windgrass`` (once); nothing is registered."""
    module = sys.modules.get(PACKAGE)
    if module is None:
        spec = importlib.util.spec_from_file_location(
            PACKAGE, REPO / "__init__.py", submodule_search_locations=[str(REPO)])
        assert spec is not None and spec.loader is not None  # (a file location always has both)
        module = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = module
        spec.loader.exec_module(module)
    return module


def load_addon(register: bool = True) -> ModuleType:
    """``load_package`` and register the add-on with Blender (needs bpy)."""
    module = load_package()
    if register and not getattr(module, "_registered", False):
        module.register()
    return module
