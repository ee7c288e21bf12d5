"""Windgrass: grass fields with three levels of detail swaying in a physical wind.

Blender extension entry point (Qiu et al., "Dynamic Simulation of Grass Field Swaying in Wind").
Thin on purpose: it registers the generated settings (``grass_addon/bridge/properties.py``), the
operators, the panels and the runtime's frame handlers. All imports are relative; the package
name comes from the extension system (``bl_ext.<repo>.windgrass``) or ``headless/addon_loader.py``.
"""

import importlib
import importlib.util

_registered = False

# Registered in this order, unregistered in reverse; runtime is optional while it is written.
_MODULES = (".grass_addon.bridge.properties", ".operators", ".panels", ".grass_addon.bridge.runtime")
_OPTIONAL = frozenset({".grass_addon.bridge.runtime"})


def _modules() -> list:
    out = []
    for name in _MODULES:
        if name in _OPTIONAL and importlib.util.find_spec(name, __name__) is None:
            continue
        out.append(importlib.import_module(name, __name__))
    return out


def register() -> None:
    """Register everything; a second call does nothing."""
    global _registered
    if _registered:
        return
    done = []
    try:
        for module in _modules():
            if hasattr(module, "register"):
                module.register()
                done.append(module)
    except Exception:
        for module in reversed(done):  # leave Blender as it was
            module.unregister()
        raise
    _registered = True


def unregister() -> None:
    """Remove everything register() added (Scene.windgrass, classes, menu entries, handlers)."""
    global _registered
    if not _registered:
        return
    for module in reversed(_modules()):
        if hasattr(module, "unregister"):
            module.unregister()
    _registered = False
