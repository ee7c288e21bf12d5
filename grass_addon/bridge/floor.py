"""Blender's floor grid and axes over the grass that EEVEE draws (issue #28 item 6).

The overlays (the floor grid, the X and Y axes) are drawn at z = 0 and hidden where the render
engine's depth says something stands in front. EEVEE hands the overlays its depth pushed back by
that depth's own change across each 2 x 2 block of pixels (its film's display pass): where a
surface is a few pixels wide, as grass blades are, that is the depth of the ground behind them,
and the grid shows through the whole sward; on the ground itself, at the grid's height, it shows
as on any plane at z = 0. Solid shading (the workbench) and Cycles (its depth pre-pass) hand the
overlays the true depth, and the grass hides the grid there.

So while a 3D view draws a grass field with EEVEE (Material Preview, or Rendered with EEVEE),
Windgrass turns that view's floor and axes off, and turns back on what it turned off when the view
no longer does (Solid shading, Cycles, the field hidden or removed). It acts when a view starts or
stops drawing grass with EEVEE, never in between: an artist who turns the floor on again keeps it
(through saves too: the record holds only what is still off).
A file is saved with the overlays as the artist set them, and the add-on's unregister gives them
back. The view timer (``handlers.watch_views``) calls ``follow_views``.
"""

from __future__ import annotations

import bpy

from . import owned
from .registry import REGISTRY

FLAGS = ("show_floor", "show_axis_x", "show_axis_y")  # what draws at z = 0 in a perspective view


def _eevee(space, scene) -> bool:
    """Whether ``space`` draws with EEVEE: Material Preview always, Rendered with the scene's engine."""
    shading = space.shading.type
    return shading == "MATERIAL" or (shading == "RENDERED" and scene.render.engine.startswith("BLENDER_EEVEE"))


def _shows_grass(scene, view_layer, space) -> bool:
    """Whether a field of ``scene`` is visible in ``view_layer`` and the 3D view ``space`` (its local
    view and collections): its ground, the field's parent, is."""
    for item in owned.scene_fields(scene):
        ground = owned.ground_object(item) if item.collection is not None else None
        if ground is not None and ground.name in view_layer.objects and \
                ground.visible_get(view_layer=view_layer, viewport=space):
            return True
    return False


def _spaces():
    """{pointer: 3D view space} of every screen (a screen not shown now keeps its views)."""
    return {area.spaces.active.as_pointer(): area.spaces.active
            for screen in bpy.data.screens for area in screen.areas if area.type == "VIEW_3D"}


def follow_views() -> None:
    """Turn the floor and axes off in each 3D view that starts drawing grass with EEVEE, back on
    in each that stops; forget views that are gone."""
    spaces = _spaces()
    for key in [k for k in REGISTRY.floors if k not in spaces]:
        del REGISTRY.floors[key]
    for window in bpy.context.window_manager.windows:
        if window.screen is None:
            continue
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            key = space.as_pointer()
            drawn = _eevee(space, window.scene) and _shows_grass(window.scene, window.view_layer, space)
            if drawn and key not in REGISTRY.floors:
                REGISTRY.floors[key] = tuple(flag for flag in FLAGS if getattr(space.overlay, flag))
                _turn(space, REGISTRY.floors[key], False)
                area.tag_redraw()
            elif not drawn and key in REGISTRY.floors:
                _turn(space, REGISTRY.floors.pop(key), True)
                area.tag_redraw()
            elif drawn:  # what the artist turned on again is theirs: a save leaves it on
                REGISTRY.floors[key] = tuple(f for f in REGISTRY.floors[key] if not getattr(space.overlay, f))


def _turn(space, flags, on: bool) -> None:
    """Turn the overlay ``flags`` of ``space`` on or off."""
    for flag in flags:
        setattr(space.overlay, flag, on)


def give_back(keep: bool) -> None:
    """Turn on what the add-on turned off, in every view: before a save (``keep``: the records
    stay, ``take_again`` turns them off after it) or for good (unregister)."""
    _turn_recorded(True)
    if not keep:
        REGISTRY.floors.clear()


def take_again() -> None:
    """After a save: turn off again what ``give_back(keep=True)`` turned on."""
    _turn_recorded(False)


def _turn_recorded(on: bool) -> None:
    spaces = _spaces()
    for key, flags in REGISTRY.floors.items():
        if key in spaces:
            _turn(spaces[key], flags, on)
