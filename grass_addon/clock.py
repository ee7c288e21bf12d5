"""The one clock of a field: frames <-> seconds (DEVELOPERS.md, time).

``t(frame, subframe) = (frame + subframe - frame_start) / fps``: 0 at the first frame, sub-frames
(Blender's motion-blur steps) in between. Inside Blender the scene's fps and start frame replace
the field's ``render.*`` values (``properties.params_from_settings(item, scene)``), so the engine,
the stored collider motion, the wind keys and the camera path all read one clock.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Clock:
    fps: int
    frame_start: int

    @classmethod
    def of(cls, params) -> Clock:
        """The clock of a field's parameters (``render.fps``, ``render.frame_start``)."""
        return cls(int(params.render.fps), int(params.render.frame_start))

    @classmethod
    def of_scene(cls, scene) -> Clock:
        """The clock of a Blender scene (anything with ``render.fps`` and ``frame_start``)."""
        return cls(int(scene.render.fps), int(scene.frame_start))

    @property
    def dt(self) -> float:
        """Seconds per frame."""
        return 1.0 / self.fps

    def seconds(self, frame, subframe: float = 0.0) -> float:
        """t of ``frame`` (+ ``subframe``) in seconds."""
        return (frame + subframe - self.frame_start) / self.fps

    def frame_at(self, t: float) -> float:
        """The (fractional) frame at ``t`` seconds."""
        return self.frame_start + t * self.fps
