"""A field's new engine built in the background, so a layout edit (density, seed, size) never holds
Blender's window while the blocks are made and the first frame is simulated.

After a slider edit in the UI (``edits.flush_pending``) a field that needs a new engine starts a
``Build``: a thread that makes the ``GrassField`` from inputs read on the main thread
(``resolve.read_inputs``: numpy only from there on, no ``bpy``) and seeks it to the frame shown.
Until it is done the field's grass is hidden and its panel says how far it is; a timer
(``poll``) takes the engine when it is ready and writes the frame on the main thread. An edit
made while one runs waits for it (one build at a time per field, never a queue): the next update
starts one more for the settings then, and a finished build whose settings are no longer the
field's is dropped. Scripts, background renders and renders in the UI build at once (``wait``).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import bpy

from ..field import GrassField

POLL_S = 0.1


@dataclass(eq=False)
class Build:
    """One engine being made on a thread for ``digest`` (``resolve.Inputs.digest``)."""

    digest: str
    frame: int
    views: object
    made: GrassField | None = None
    error: BaseException | None = None
    done: threading.Event = field(default_factory=threading.Event)
    progress: tuple[int, int] = (0, 0)  # (frames simulated, of) the first seek

    def start(self, make) -> Build:
        """Run ``make(report) -> GrassField`` on a thread, then the first seek."""
        def run() -> None:
            try:
                engine = make(self._report)
                engine.view(self.views, self.frame)
                engine.seek(self.frame)
                self.made = engine
            except BaseException as exc:  # (handed to the main thread, which reports it)
                self.error = exc
            finally:
                self.done.set()

        threading.Thread(target=run, name=f"windgrass build {self.digest[:8]}", daemon=True).start()
        return self

    def _report(self, done: int, total: int) -> None:
        self.progress = (done, total)

    def wait(self) -> None:
        self.done.wait()

    def percent(self) -> int:
        done, total = self.progress
        return int(100 * done / total) if total else 0


class BuildPending(Exception):  # noqa: N818 (a signal, not an error: the grass shows when it is built)
    """The field's new engine is being built in the background (``Build``): nothing to write yet."""


def poll_later() -> None:
    """Look again for finished builds shortly (a timer)."""
    if not bpy.app.timers.is_registered(poll):
        bpy.app.timers.register(poll, first_interval=POLL_S)


def poll() -> float | None:
    """Timer: write the fields whose build is done; run again while one is not."""
    from . import properties
    from .frame_pass import guarded, update_field
    from .registry import REGISTRY

    running = False
    scenes = {s.session_uid: s for s in bpy.data.scenes}
    for key, state in list(REGISTRY.states.items()):
        job = state.building
        if job is None:
            continue
        if not job.done.is_set():
            running = True
            continue
        scene = scenes.get(key[0])
        item = properties.field_by_uid(scene, key[1]) if scene else None
        if item is None:
            state.build_dropped()
            continue
        guarded(update_field, scene, item, wait=False)
        running = running or state.building is not None
        _redraw()
    return POLL_S if running else None


def _redraw() -> None:
    wm = bpy.context.window_manager
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type in ("VIEW_3D", "PROPERTIES"):
                area.tag_redraw()
