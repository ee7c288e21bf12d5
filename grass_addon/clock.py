"""The one clock of a field: frames <-> seconds (DEVELOPERS.md, time).

``t(frame, subframe) = (frame + subframe - frame_start) * fps_base / fps``: 0 at the first frame,
sub-frames (Blender's motion-blur steps) in between; ``fps / fps_base`` is Blender's frame rate
(29.97 fps is 30 / 1.001). Inside Blender ``Clock.of_scene`` is the only reader of the scene's clock
and ``properties.params_from_settings(item, scene)`` writes it over the field's ``render.*``
values, so the engine, the stored collider motion, the wind keys and the camera path all read one
clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from .schema import Params


@dataclass(frozen=True)
class Clock:
    fps: int
    frame_start: int
    fps_base: float = 1.0

    @classmethod
    def of(cls, params: Params) -> Clock:
        """The clock of a field's parameters (``render.fps``, ``fps_base``, ``frame_start``)."""
        r = params.render
        return cls(int(r.fps), int(r.frame_start), float(r.fps_base))

    @classmethod
    def of_scene(cls, scene) -> Clock:
        """The clock of a Blender scene: ``render.fps``, ``render.fps_base`` and ``frame_start``."""
        return cls(int(scene.render.fps), int(scene.frame_start), float(scene.render.fps_base))

    @property
    def rate(self) -> float:
        """Frames per second (fps / fps_base)."""
        return self.fps / self.fps_base

    @property
    def dt(self) -> float:
        """Seconds per frame."""
        return self.fps_base / self.fps

    def frames(self, seconds: float) -> int:
        """Whole frames nearest ``seconds`` (a warm-up, an epoch)."""
        return int(round(seconds * self.rate))

    def seconds(self, frame, subframe: float = 0.0) -> float:
        """t of ``frame`` (+ ``subframe``) in seconds."""
        return (frame + subframe - self.frame_start) * self.fps_base / self.fps

    def frame_at(self, t: float) -> float:
        """The (fractional) frame at ``t`` seconds."""
        return self.frame_start + t * self.fps / self.fps_base
