"""The one piece of module-level state of the add-on: every field's runtime, by key.

A key is ``(scene.session_uid, field uid)``: Blender keeps a scene's session uid through renames
and undo and gives a copied scene a new one. Nothing in the .blend refers to a runtime: the
registry is emptied on file load and each field is resolved again from its stored settings (the
state at frame N is a function of the parameters, the seed and N).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

Key = tuple[int, str]


def key_of(scene, item) -> Key:
    return scene.session_uid, str(item.uid)


@dataclass
class Registry:
    fields: dict[Key, Any] = field(default_factory=dict)  # Key -> runtime.FieldRuntime
    errors: dict[Key, str] = field(default_factory=dict)  # why a field cannot be simulated now
    pending: dict[Key, float] = field(default_factory=dict)  # edits waiting to settle (UI), by time
    terrains: dict[Key, tuple] = field(default_factory=dict)  # (terrain key, heightfield, centre) sampled
    paints: dict[Key, tuple] = field(default_factory=dict)  # (what it was read from, paint.Paint | None)
    paint_deps: dict[Key, set] = field(default_factory=dict)  # (ID type, name) of what a field's paint reads
    strokes: dict[Key, int] = field(default_factory=dict)  # edits of those datablocks since (painting)
    stroke_s: dict[Key, float] = field(default_factory=dict)  # seconds the field's last stroke took to show
    stroked: set = field(default_factory=set)  # fields with a stroke waiting to be shown
    warned: set[str] = field(default_factory=set)  # console messages already printed
    saved_bakes: set = field(default_factory=set)  # cache files the .blend on disk refers to
    bake_root: str | None = None  # <blend>_windgrass of the open file
    last_repaint: tuple = ()  # (seconds, blocks made again) of the last stroke applied
    tracks: dict[str, tuple] = field(default_factory=dict)  # stored motion decoded: fingerprint -> (colliders, fields)
    motion: set = field(default_factory=set)  # fields whose colliders or force fields were edited
    sampling: bool = False  # tracks.sample is stepping the scene's frames: the handlers stay out
    rendering: bool = False  # between render_pre and render_post/render_cancel: the scene camera rules
    batch_depth: int = 0  # > 0 while properties.batch writes many settings: one update at the end

    def clear(self) -> None:
        self.fields.clear()
        self.errors.clear()
        self.pending.clear()
        self.terrains.clear()
        self.paints.clear()
        self.paint_deps.clear()
        self.strokes.clear()
        self.stroke_s.clear()
        self.stroked.clear()
        self.tracks.clear()
        self.motion.clear()
        self.warned.clear()

    def forget_missing(self, alive: set[Key]) -> None:
        """Drop the runtimes of scenes or fields that no longer exist."""
        for table in (self.fields, self.errors, self.pending, self.terrains, self.paints, self.paint_deps,
                      self.strokes, self.stroke_s):
            for key in [k for k in table if k not in alive]:
                del table[key]


REGISTRY = Registry()


def warn_once(text: str) -> None:
    """Report a problem in the console once; a frame handler must never raise into Blender."""
    if text not in REGISTRY.warned:
        REGISTRY.warned.add(text)
        print(f"Windgrass: {text}")
