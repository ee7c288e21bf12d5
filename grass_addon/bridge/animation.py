"""Animated wind: the field's wind speed and direction F-curves as keys for the engine.

The solver reads the wind once per frame (paper IV), so an animated speed or direction becomes one
key per frame, from the simulation's start to the scene's end (``sample_range``), in the engine's
clock ``t = (frame - frame_start) / fps``. The F-curves' fingerprint tells when they changed.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ..clock import Clock
from ..schema import Params

# Past frame_end the sampled range grows in steps of this many frames, so the keys (and the
# fingerprint) rarely change while a user plays on.
EXTEND_FRAMES = 240


def action_fcurves(anim_data):
    """F-curves of the animation data's action; Blender 4.4+ layered actions use channelbags
    (``action.fcurves`` is gone in 5.0)."""
    action = anim_data.action if anim_data is not None else None
    if action is None:
        return ()
    slot = getattr(anim_data, "action_slot", None)
    try:
        from bpy_extras import anim_utils
        get_bag = getattr(anim_utils, "action_get_channelbag_for_slot", None)
    except ImportError:  # pragma: no cover
        get_bag = None
    if get_bag is not None and slot is not None:
        bag = get_bag(action, slot)
        return tuple(bag.fcurves) if bag is not None else ()
    return tuple(getattr(action, "fcurves", ()))


def wind_fcurves(scene, item) -> dict[str, object]:
    """{'speed': fcurve, 'direction': fcurve} of this field's animated wind, if any."""
    base = item.path_from_id("wind")
    wanted = {f"{base}.speed": "speed", f"{base}.direction": "direction"}
    out = {}
    for fc in action_fcurves(scene.animation_data):
        role = wanted.get(fc.data_path)
        if role is not None and not fc.mute:
            out[role] = fc
    return out


def fcurve_fingerprint(fc) -> bytes:
    """Every key, handle, interpolation and setting of an F-curve, as bytes."""
    n = len(fc.keyframe_points)
    data = np.empty(n * 6, dtype=np.float32)
    if n:
        fc.keyframe_points.foreach_get("co", data[: 2 * n])
        fc.keyframe_points.foreach_get("handle_left", data[2 * n: 4 * n])
        fc.keyframe_points.foreach_get("handle_right", data[4 * n:])
    extra = f"{fc.extrapolation}|{len(fc.modifiers)}|" + ",".join(k.interpolation for k in fc.keyframe_points)
    return data.tobytes() + extra.encode()


def sample_range(scene, params: Params) -> tuple[int, int]:
    """Frames from the simulation start (t = -preroll) to frame_end, extended in steps when the
    current frame lies beyond it, so the range (and the cache key) rarely changes."""
    first = math.floor(Clock.of(params).frame_at(-params.simulation.preroll))
    last = params.render.frame_end
    if scene.frame_current > last:
        last += int(math.ceil((scene.frame_current - last) / EXTEND_FRAMES)) * EXTEND_FRAMES
    return first, last


def sample_wind_keys(fcurves: dict, params: Params, frames: tuple[int, int]) -> tuple:
    """(time_s, speed_m_s, direction_deg) per frame from the F-curves (one sample a frame).

    Time follows the engine's clock t = (frame - frame_start) / fps; direction F-curves hold
    radians (Blender's angle unit) and become degrees (the schema's unit).
    """
    clock = Clock.of(params)
    frame_list = range(frames[0], frames[1] + 1)
    speed_fc, dir_fc = fcurves.get("speed"), fcurves.get("direction")
    speeds = [max(0.0, speed_fc.evaluate(f)) if speed_fc else params.wind.speed for f in frame_list]
    dirs = [math.degrees(dir_fc.evaluate(f)) if dir_fc else params.wind.direction for f in frame_list]
    return tuple((clock.seconds(f), float(s), float(d)) for f, s, d in zip(frame_list, speeds, dirs))


def fingerprint(fcurves: dict, frames: tuple[int, int]) -> str:
    """What the sampled keys depend on: the range and every key, handle and setting of the curves."""
    h = hashlib.sha1(repr(frames).encode())
    for role in sorted(fcurves):
        h.update(role.encode())
        h.update(fcurve_fingerprint(fcurves[role]))
    return h.hexdigest()
