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
engine it was made from, which goes on showing its frames meanwhile). A finished one is taken even
when the settings moved on while it ran (a slider still dragged): the grass follows the drag, one
run behind.

Before a build's first frame (its warm-up: most of a run's time) the thread works out a first
look (``GrassField.first_look``: 0.75 s of the wind from rest), which the timer writes at once
into the objects when they fit it: the edit shows in a fraction of the time, and the exact frame
replaces it when done. Add Grass Field from the menu builds this way too
(``edits.build_in_background``).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from ..field import FIRST_LOOK_BLOCKS, GrassField


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
    inputs: object = None  # resolve.Inputs it is made for
    base: object = None  # registry.Engine whose twin it retunes, else None (a new engine)
    painted: str = ""  # paint.fingerprint of the paint the base grew when its twin was made
    # The engine's first look (``GrassField.first_look``) once worked out on the thread, to be
    # written while its first frame is (``edits.poll_builds``), and whether one is worked out at all
    first_look: GrassField | None = None
    looks_first: bool = False
    shows_first_look: bool = False  # its first look is drawn now (the panel says so)
    # the slot pools a new field's first look was written through, while nothing else has written
    # the field's slots since: the engine takes them (``resolve._install``), so its first frame
    # writes the positions, not again each block's colours and marks
    look_pools: dict | None = None
    # its blocks are made and its first look worked out (or not wanted, or it failed first): what
    # the far grass's look, on its own thread, waits for (``look.hold``)
    looked: threading.Event = field(default_factory=threading.Event)

    def start(self, make, first_look: bool = False) -> Build:
        """Run ``make(report) -> GrassField`` on a thread, then the first seek; with
        ``first_look``, a first look of the engine is worked out before the seek (``first_look``)."""
        self.looks_first = first_look

        def run() -> None:
            try:
                engine = make(self.report)
                early = first_look and self.base is None  # (a new field: nothing of it drawn yet)
                if early:  # its look, its detail nearer (``FIRST_LOOK_BLOCKS``), makes the near blocks first
                    self._look_first(engine, FIRST_LOOK_BLOCKS)
                    self.looked.set()
                engine.view(self.views, self.at_frame)  # (a new field's blocks are made here)
                if first_look and not early:
                    self._look_first(engine)
                self.looked.set()
                engine.prepare_frame(self.at_frame, self.views)  # (the first write after it is quick)
                self.made = engine
            except BaseException as exc:  # (handed to the main thread, which reports it)
                self.failure = exc
            finally:
                self.looked.set()
                self.done.set()

        threading.Thread(target=run, name=f"windgrass build {self.digest[:8]}", daemon=True).start()
        return self

    def _look_first(self, engine: GrassField, most_blocks: int = 0) -> None:
        try:
            look = engine.first_look(most_blocks=most_blocks)
            look.view(self.views, self.at_frame)
            engine.cache.adopt(look.cache)  # (the blocks it made: the engine's view makes the others)
            if self.base is None:  # (a new field's slots are all written: their colours worked out here)
                look.prepare_frame(self.at_frame, self.views)
            else:  # (a run's slots keep their blocks and colours: the write works out the vertices)
                look.seek(self.at_frame)
        except Exception:  # (a preview only: the run after it meets and reports what is wrong)
            self.looks_first = False
            return
        self.first_look = look

    def first_look_shown(self, written: bool = False, pools: dict | None = None) -> None:
        """The first look was ``written`` (through a new field's ``pools``), or is no longer
        wanted or shown: let it go."""
        self.first_look, self.looks_first, self.shows_first_look = None, False, written
        self.look_pools = pools if written else None

    def report(self, done: int, total: int) -> None:
        self.progress = (done, total)

    def wait(self) -> None:
        self.done.wait()

    def percent(self) -> int:
        done, total = self.progress
        return int(100 * done / total) if total else 0


class BuildPending(Exception):  # noqa: N818 (a signal, not an error: the grass shows when it is built)
    """The field's new engine is being built in the background (``Build``): nothing to write yet."""
