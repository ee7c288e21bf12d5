"""The one piece of module-level state of the add-on: a record per field, by key, and a few flags.

A key is ``(scene.session_uid, field uid)``: Blender keeps a scene's session uid through renames
and undo and gives a copied scene a new one. Nothing in the .blend refers to a record: the
registry is emptied on file load and each field is resolved again from its stored settings (the
state at frame N is a function of the parameters, the seed and N). A field's record goes as one
(``forget``, ``forget_missing``), so nothing of a deleted field is left behind.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

Key = tuple[int, str]


def key_of(scene, item) -> Key:
    return scene.session_uid, str(item.uid)


@dataclass(eq=False)
class FieldState:
    """What the add-on keeps of one field between frames and edits."""

    runtime: Any = None  # resolve.FieldRuntime, or None until resolved (again)
    error: str | None = None  # why the field cannot be simulated now (its grass is hidden)
    pending: float | None = None  # time.monotonic() of an edit waiting to settle (UI), else None
    terrain: tuple | None = None  # (terrain key, heightfield, centre) as sampled
    paint: tuple | None = None  # (what it was read from, paint.Paint | None)
    paint_deps: frozenset = frozenset()  # (ID type, name) of the datablocks its paint reads
    strokes: int = 0  # edits of those datablocks so far (painting)
    stroke_s: float = 0.0  # seconds its last stroke took to show
    stroked: bool = False  # a stroke waits to be shown
    motion: bool = False  # its colliders or force fields were edited: look at their stored motion
    hidden_for_paint: bool | None = None  # hidden in the viewport while its terrain is painted (None: not yet set)


@dataclass
class Registry:
    states: dict[Key, FieldState] = field(default_factory=dict)
    warned: set[str] = field(default_factory=set)  # console messages already printed
    saved_bakes: set = field(default_factory=set)  # cache files the .blend on disk refers to
    bake_root: str | None = None  # <blend>_windgrass of the open file
    last_repaint: tuple = ()  # (seconds, blocks made again) of the last stroke applied
    tracks: dict[str, tuple] = field(default_factory=dict)  # stored motion decoded: fingerprint -> (colliders, fields)
    sampling: bool = False  # tracks.sample is stepping the scene's frames: the handlers stay out
    rendering: bool = False  # between render_pre and render_post/render_cancel: the scene camera rules
    batch_depth: int = 0  # > 0 while properties.batch writes many settings: one update at the end
    # the open file is as saved or loaded, but for the grass the add-on wrote since (its own writes
    # mark the file dirty: refilling the slots after a save, every frame's vertices)
    unchanged: bool = False
    # the 3D views drawing a field with EEVEE now: the overlays turned off in each (floor.py)
    floors: dict[int, tuple] = field(default_factory=dict)

    def state(self, key: Key) -> FieldState:
        """The record of the field ``key`` (made when there is none)."""
        found = self.states.get(key)
        if found is None:
            found = self.states[key] = FieldState()
        return found

    def runtime(self, key: Key):
        """The field's runtime, or None."""
        found = self.states.get(key)
        return None if found is None else found.runtime

    @property
    def fields(self) -> dict:
        """{key: runtime} of the fields resolved now."""
        return {key: s.runtime for key, s in self.states.items() if s.runtime is not None}

    def clear(self) -> None:
        self.states.clear()
        self.tracks.clear()
        self.warned.clear()
        self.floors.clear()  # (another file's views, or none)

    def forget_missing(self, alive: set[Key]) -> None:
        """Drop the records of scenes or fields that no longer exist."""
        for key in [k for k in self.states if k not in alive]:
            del self.states[key]


REGISTRY = Registry()


def warn_once(text: str) -> None:
    """Report a problem in the console once; a frame handler must never raise into Blender."""
    if text not in REGISTRY.warned:
        REGISTRY.warned.add(text)
        print(f"Windgrass: {text}")
