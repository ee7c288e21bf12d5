"""Shared by the operators: error reporting, poll and refresh."""

import functools
from collections.abc import Callable
from typing import Any

from ..grass_addon.bridge import runtime
from ..grass_addon.bridge.runtime import WindgrassError, properties


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


def active_field(scene: Any) -> Any:
    """The scene's active field item; a WindgrassError (an ERROR report under ``reported``) when
    the scene has none: an operator whose poll passed may still be called where it has none."""
    item = properties.active_field(scene) if scene is not None else None
    if item is None:
        raise WindgrassError("this scene has no grass field: add one with Add > Grass Field")
    return item


def has_active_field(context: Any) -> bool:
    scene = getattr(context, "scene", None)
    return scene is not None and properties.active_field(scene) is not None


def refresh(scene: Any) -> None:
    """Let the runtime write the scene's fields for the current frame."""
    runtime.update_scene(scene)
