"""Windgrass: grass fields with three levels of detail swaying in a physical wind.

Blender extension entry point (Qiu et al., "Dynamic Simulation of Grass Field Swaying in Wind").
Thin on purpose: it registers the generated settings (``grass_addon/bridge/properties.py``), the
operators, the panels and the runtime's frame handlers. All imports are relative; the package
name comes from the extension system (``bl_ext.<repo>.windgrass``) or ``headless/addon_loader.py``.
"""

import importlib

_registered = False

# Registered in this order, unregistered in reverse.
_MODULES = (".grass_addon.bridge.module_exit", ".grass_addon.bridge.properties", ".operators", ".panels",
            ".grass_addon.bridge.runtime")


def _modules() -> list:
    return [importlib.import_module(name, __name__) for name in _MODULES]


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
    except Exception:  # whatever failed, leave Blender as it was before raising it
        for module in reversed(done):
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
