"""Load the repository as the add-on package, without installing it (tests and headless scripts).

The repository root is the extension; its package name is the manifest id, ``windgrass``.
Inside the extension all imports are relative, so the name only appears here.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parent.parent
PACKAGE = "windgrass"


def load_addon(register: bool = True) -> ModuleType:
    """Import the repo root as package ``windgrass`` (once) and register it with Blender."""
    module = sys.modules.get(PACKAGE)
    if module is None:
        spec = importlib.util.spec_from_file_location(
            PACKAGE, REPO / "__init__.py", submodule_search_locations=[str(REPO)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = module
        spec.loader.exec_module(module)
    if register and not getattr(module, "_registered", False):
        module.register()
    return module


def core() -> ModuleType:
    """The numpy-only engine package ``grass_addon`` (importable without bpy)."""
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    import grass_addon

    return grass_addon
