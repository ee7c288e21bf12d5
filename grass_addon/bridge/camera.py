"""The scene camera as the engine's ``lod.Camera``, in the field's frame."""

from __future__ import annotations

import math

import numpy as np

from ..lod import Camera
from . import scene as field_scene


def blender_camera(scene, to_field=None, depsgraph=None):
    """``lod.Camera`` of the scene camera in the field's frame, or None without a camera.

    With ``depsgraph`` the evaluated camera is used (its animation at this frame)."""
    cam = scene.camera
    if cam is None or cam.type != "CAMERA":
        return None
    if depsgraph is not None:
        cam = cam.evaluated_get(depsgraph)
    matrix = cam.matrix_world
    if to_field is not None:
        matrix = to_field @ matrix
    rot = np.array(matrix.to_3x3(), dtype=np.float64)
    position = np.array(matrix.translation, dtype=np.float64)
    forward = -rot[:, 2]  # a Blender camera looks down its local -Z
    up = rot[:, 1]
    forward /= max(np.linalg.norm(forward), 1e-12)
    up /= max(np.linalg.norm(up), 1e-12)
    r = scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / max(r.resolution_y * r.pixel_aspect_y, 1e-9)
    data = cam.data
    if data.type == "ORTHO":
        # No perspective: take the angle that shows the ortho width from the camera's distance
        # to the field centre (LOD distances still come from the camera position).
        dist = max(float(np.linalg.norm(position)), 1e-3)
        fov_x = 2.0 * math.atan(0.5 * data.ortho_scale / dist)
    else:
        fit = data.sensor_fit
        if fit == "AUTO":
            # The sensor width spans the larger image side.
            fov_x = data.angle_x if aspect >= 1.0 else 2.0 * math.atan(math.tan(0.5 * data.angle_x) * aspect)
        elif fit == "HORIZONTAL":
            fov_x = data.angle_x
        else:
            fov_x = 2.0 * math.atan(math.tan(0.5 * data.angle_y) * aspect)
    fov_x = min(max(fov_x, 1e-3), math.radians(179.0))
    return Camera(position=position.astype(np.float32), forward=forward.astype(np.float32),
                  up=up.astype(np.float32), fov_x=float(fov_x), aspect=float(aspect))


def signature(camera) -> tuple | None:
    if camera is None:
        return None
    return (tuple(np.round(camera.position, 6)), tuple(np.round(camera.forward, 6)),
            tuple(np.round(camera.up, 6)), round(camera.fov_x, 6), round(camera.aspect, 6))


def field_camera(scene, item, depsgraph=None):
    """The scene camera in the field's frame (the ground object's inverse world matrix)."""
    ground = field_scene.ground_object(item)
    if ground is not None and depsgraph is not None:
        ground = ground.evaluated_get(depsgraph)
    to_field = ground.matrix_world.inverted_safe() if ground is not None else None
    return blender_camera(scene, to_field, depsgraph)


