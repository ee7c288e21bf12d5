"""A field's new engine built in the background, so a layout edit (density, seed, size) never holds
Blender's window while the blocks are made and the first frame is simulated.

After a slider edit in the UI (``edits.flush_pending``) a field that needs a new engine starts a
``Build``: a thread that makes the ``GrassField`` from inputs read on the main thread
(``resolve.read_inputs``: numpy only from there on, no ``bpy``) and seeks it to the frame shown.
Until it is done the field's grass is hidden and its panel says how far it is; a timer
(``edits.poll_builds``) takes the engine when it is ready and writes the frame on the main thread.
An edit made while one runs waits for it (one build at a time per field, never a queue): the next
update starts one more for the settings then, and a finished build whose settings are no longer
the field's is dropped. Scripts, background renders and renders in the UI build at once (``wait``).

An edit of the wind or the solver keeps the field's blocks but simulates again (seconds on a large
field): in the UI that run is a ``Build`` too, of the engine's ``twin`` retuned (``base``: the
engine it was made from, which goes on showing its frames meanwhile). Before it the thread works
out a first look (another twin, ``GrassField.glimpse``: 0.75 s of the new wind from rest),
which the timer writes at once: the edit shows in a tenth of the run's time, and the run's exact
frame replaces it when done. A finished one is taken even
when the settings moved on while it ran (a slider still dragged): the grass follows the drag, one
run behind.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from ..field import GrassField


@dataclass(eq=False)
class Build:
    """One engine being made on a thread for ``digest`` (``resolve.Inputs.digest``)."""

    digest: str
    at_frame: int
    views: object
    made: GrassField | None = None
    failure: BaseException | None = None
    done: threading.Event = field(default_factory=threading.Event)
    progress: tuple[int, int] = (0, 0)  # (frames simulated, of) the first seek
    inputs: object = None  # resolve.Inputs it is made for (a retune: ``base`` is set)
    base: object = None  # registry.Engine whose twin it retunes, else None (a new engine)
    painted: str = ""  # paint.fingerprint of the paint the base grew when its twin was made
    # A retune's first look (``GrassField.glimpse``) once worked out on the thread, to be written
    # while the run goes on (``edits.poll_builds``), and whether one is worked out at all
    first_look: GrassField | None = None
    looks_first: bool = False

    def start(self, make, first=None) -> Build:
        """Run ``make(report) -> GrassField`` on a thread, then the first seek; ``first() ->
        GrassField``: a first look worked out before it (``first_look``)."""
        self.looks_first = first is not None

        def run() -> None:
            nonlocal first
            try:
                if first is not None:
                    self._look_first(first)
                    first = None  # (the first look is the timer's now: not kept through the run)
                engine = make(self.report)
                engine.view(self.views, self.at_frame)
                engine.prepare_frame(self.at_frame, self.views)  # (the first write after it is quick)
                self.made = engine
            except BaseException as exc:  # (handed to the main thread, which reports it)
                self.failure = exc
            finally:
                self.done.set()

        threading.Thread(target=run, name=f"windgrass build {self.digest[:8]}", daemon=True).start()
        return self

    def _look_first(self, first) -> None:
        try:
            glimpse = first()
            glimpse.view(self.views, self.at_frame)
            glimpse.prepare_frame(self.at_frame, self.views)
        except Exception:  # (a preview only: the run after it meets and reports what is wrong)
            self.looks_first = False
            return
        self.first_look = glimpse

    def first_look_shown(self) -> None:
        """The first look was written (or is no longer wanted): let it go."""
        self.first_look, self.looks_first = None, False

    def report(self, done: int, total: int) -> None:
        self.progress = (done, total)

    def wait(self) -> None:
        self.done.wait()

    def percent(self) -> int:
        done, total = self.progress
        return int(100 * done / total) if total else 0


class BuildPending(Exception):  # noqa: N818 (a signal, not an error: the grass shows when it is built)
    """The field's new engine is being built in the background (``Build``): nothing to write yet."""
