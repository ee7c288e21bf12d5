"""The views a field's levels of detail follow, as the engine's ``lod.Camera`` in the field's frame.

* Renders (F12, animations, background Blender, ``render_field.py``): the scene camera, with its
  lens shift, orthographic scale or panoramic projection. A render therefore depends on the frame
  and the scene camera alone, never on how the artist's viewport looked.
* The artist's viewport: every open 3D view, through its own eye (its perspective or
  orthographic view; in camera view the camera it looks through), so the grass is drawn around
  wherever the artist orbits and zooms, in several views at once. Without a 3D view (a script
  in a window with none), the scene camera.
"""

from __future__ import annotations

import math

import numpy as np

from ..lod import ORTHOGRAPHIC, PANORAMIC, PERSPECTIVE, Camera
from . import owned
from .registry import REGISTRY

# Blender draws a 3D view with a 36 mm sensor at twice the zoom of a camera (CAMERA_PARAM_ZOOM_INIT_PERSP):
# its lens of 50 mm shows what a 50 mm lens on a 72 mm sensor would.
VIEWPORT_SENSOR = 72.0


def _basis(matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position, forward, up) of a camera-to-world matrix (a camera looks down its local -Z)."""
    rot = np.array(matrix.to_3x3(), dtype=np.float64)
    position = np.array(matrix.translation, dtype=np.float64)
    forward, up = -rot[:, 2], rot[:, 1]
    forward /= max(float(np.linalg.norm(forward)), 1e-12)
    up /= max(float(np.linalg.norm(up)), 1e-12)
    return position, forward, up


def _fov_x(angle_larger_side: float, aspect: float) -> float:
    """Horizontal field of view from the angle across the image's larger side (sensor fit AUTO)."""
    if aspect >= 1.0:
        return angle_larger_side
    return 2.0 * math.atan(math.tan(0.5 * angle_larger_side) * aspect)


def _camera_object(cam, aspect: float, to_field=None, depsgraph=None, pixels: float = 0.0) -> Camera | None:
    """``lod.Camera`` of a camera object (its lens, sensor fit, shift, projection) for an image
    ``pixels`` wide."""
    if cam is None or cam.type != "CAMERA":
        return None
    if depsgraph is not None:
        cam = cam.evaluated_get(depsgraph)
    matrix = cam.matrix_world if to_field is None else to_field @ cam.matrix_world
    position, forward, up = _basis(matrix)
    data = cam.data
    shift = (float(data.shift_x), float(data.shift_y))
    if data.type == "PANO":
        return Camera(position, forward, up, math.radians(179.0), aspect, projection=PANORAMIC)
    if data.type == "ORTHO":
        # ortho_scale spans the image's larger side (sensor fit AUTO; the others alike here)
        width = data.ortho_scale if aspect >= 1.0 else data.ortho_scale * aspect
        return Camera(position, forward, up, 0.0, aspect, projection=ORTHOGRAPHIC, ortho_width=float(width),
                      shift=shift)
    fit = data.sensor_fit
    if fit == "AUTO":
        fov_x = _fov_x(data.angle_x, aspect)  # the sensor width spans the larger image side
    elif fit == "HORIZONTAL":
        fov_x = data.angle_x
    else:
        fov_x = 2.0 * math.atan(math.tan(0.5 * data.angle_y) * aspect)
    fov_x = min(max(fov_x, 1e-3), math.radians(179.0))
    return Camera(position, forward, up, float(fov_x), float(aspect), shift=shift, pixels=float(pixels))


def render_pixels(scene) -> float:
    """The rendered image's width in pixels (the resolution at its percentage)."""
    r = scene.render
    return float(r.resolution_x) * float(r.resolution_percentage) / 100.0


def render_aspect(scene) -> float:
    r = scene.render
    return (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-9)


def blender_camera(scene, to_field=None, depsgraph=None) -> Camera | None:
    """``lod.Camera`` of the scene camera in the field's frame, or None without a camera.

    With ``depsgraph`` the evaluated camera is used (its animation at this frame)."""
    return _camera_object(scene.camera, render_aspect(scene), to_field, depsgraph, render_pixels(scene))


def _view3d_camera(space, region, r3d, scene, to_field, depsgraph) -> Camera | None:
    """``lod.Camera`` of one 3D view region: its own eye, or in camera view the camera."""
    aspect = region.width / max(region.height, 1)
    if r3d.view_perspective == "CAMERA":
        cam = space.camera if space.use_local_camera and space.camera is not None else scene.camera
        return _camera_object(cam, render_aspect(scene), to_field, depsgraph, float(region.width))
    matrix = r3d.view_matrix.inverted()
    if to_field is not None:
        matrix = to_field @ matrix
    position, forward, up = _basis(matrix)
    if r3d.view_perspective == "ORTHO":
        width = 2.0 * r3d.view_distance * (VIEWPORT_SENSOR / 2.0) / space.lens
        width = width if aspect >= 1.0 else width * aspect
        return Camera(position, forward, up, 0.0, aspect, projection=ORTHOGRAPHIC, ortho_width=float(width))
    fov = 2.0 * math.atan(0.5 * VIEWPORT_SENSOR / space.lens)
    return Camera(position, forward, up, float(min(_fov_x(fov, aspect), math.radians(179.0))), float(aspect),
                  projection=PERSPECTIVE, pixels=float(region.width))


def viewport_views(context, scene, to_field=None, depsgraph=None) -> list[Camera]:
    """Every 3D view of every window showing ``scene`` (quad views: each of the four)."""
    out = []
    wm = getattr(context, "window_manager", None)
    for window in wm.windows if wm is not None else ():
        if window.scene != scene:
            continue
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            regions = [r for r in area.regions if r.type == "WINDOW" and r.width > 1 and r.height > 1]
            quads = list(space.region_quadviews) if getattr(space, "region_quadviews", None) else []
            r3ds = quads if len(quads) == len(regions) and quads else [space.region_3d] * len(regions[:1])
            for region, r3d in zip(regions, r3ds):
                view = _view3d_camera(space, region, r3d, scene, to_field, depsgraph)
                if view is not None:
                    out.append(view)
    return out


def rendering() -> bool:
    """True while Blender renders (F12, an animation) or runs without a window."""
    import bpy

    return bpy.app.background or REGISTRY.rendering or bpy.app.is_job_running("RENDER")


def field_views(scene, item, depsgraph=None) -> list[Camera]:
    """The views the field follows now (see the module docstring), in the field's frame (the
    ground object's inverse world matrix); empty when there is none (no camera, no 3D view)."""
    import bpy

    ground = owned.ground_object(item)
    if ground is not None and depsgraph is not None:
        ground = ground.evaluated_get(depsgraph)
    to_field = ground.matrix_world.inverted_safe() if ground is not None else None
    if not rendering():
        views = viewport_views(bpy.context, scene, to_field, depsgraph)
        if views:
            return views
    cam = blender_camera(scene, to_field, depsgraph)
    return [] if cam is None else [cam]


def signature(views) -> tuple:
    """What the views are, rounded: equal signatures draw the same LOD."""
    if views is None:
        return ()
    if isinstance(views, Camera):
        views = [views]
    return tuple((tuple(np.round(v.position, 6)), tuple(np.round(v.forward, 6)), tuple(np.round(v.up, 6)),
                  round(v.fov_x, 6), round(v.aspect, 6), v.projection, round(v.ortho_width, 6),
                  tuple(np.round(v.shift, 6)), round(float(v.pixels), 3)) for v in views)
