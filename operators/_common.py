"""Shared by the operators: lazy access to the bridge modules and error reporting."""

import functools
import importlib
import importlib.util
from collections.abc import Callable
from types import ModuleType
from typing import Any

from ..grass_addon.bridge import properties
from ..grass_addon.errors import WindgrassError

_BRIDGE = __package__.rpartition(".")[0] + ".grass_addon.bridge"


def bridge(name: str) -> ModuleType:
    """``grass_addon.bridge.<name>`` imported on first use (it may be written after this file)."""
    module_name = f"{_BRIDGE}.{name}"
    if importlib.util.find_spec(module_name) is None:
        raise WindgrassError(f"Windgrass is incomplete: grass_addon/bridge/{name}.py is missing")
    return importlib.import_module(module_name)


def optional_bridge(name: str) -> ModuleType | None:
    """Like ``bridge`` but None when the module does not exist."""
    try:
        return bridge(name)
    except WindgrassError:
        return None


def reported(execute: Callable) -> Callable:
    """Decorate ``execute``: a WindgrassError (ParameterError included) becomes an ERROR report
    with the message naming the parameter, and the operator is cancelled."""

    @functools.wraps(execute)
    def wrapper(self: Any, context: Any) -> set[str]:
        try:
            return execute(self, context)
        except WindgrassError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}

    return wrapper


def has_active_field(context: Any) -> bool:
    scene = getattr(context, "scene", None)
    return scene is not None and properties.active_field(scene) is not None


def refresh(scene: Any) -> None:
    """Let the runtime write the scene's fields for the current frame (if it is there)."""
    runtime = optional_bridge("runtime")
    update = getattr(runtime, "update_scene", None)
    if update is not None:
        update(scene)
