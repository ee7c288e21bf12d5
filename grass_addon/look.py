"""The field's look worked out from its settings: the values its materials show that take time to
compute (numpy only): the far sward's colours over the rays' slopes, its depth profile and grain
(``sward``), the card atlas (``atlas``), the meadow's patch maps, the floor's colours.

Each is kept by the settings it reads (``edit_parts.remembered``): ``prepare(params)`` computes
them all, and the bridge's writes into the materials afterwards take milliseconds. An edit in
Blender's UI asks for them on a thread (``ask``), so a slider dragged never holds the window while
a look of a second or two is worked out: one thread at a time, and the settings asked for last are
the next it works on (never a queue); the bridge writes the materials when ``ask`` says they are
ready.
"""

from __future__ import annotations

import threading
import time

from . import atlas, sward
from .schema import Params


def _parts(params: Params, own=None) -> list[tuple]:
    """(function, arguments, keywords) of every part of the look, as the bridge asks for them
    (``own``: the artist's plants the cards draw, ``plants.Plants``; none: not passed)."""
    slopes = sward.look_slopes()[1]
    parts: list[tuple] = [
        (sward.sward_look, (params, slopes)), (sward.sward_look, (params, [sward.VIEWPORT_SLOPE])),
        (sward.grain_seen, (params, slopes)), (sward.ground_colours, (params,)), (sward.canopy_height, (params,)),
        (sward.fringe_top, (params,)), (sward.fringe_colour, (params,)), (sward.sward_profile, (params,)),
        (sward.tussock_grain, (params,)), (sward.flower_speckles, (params,)), (sward.patch_tint, (params,)),
        (sward.patch_stands, (params,))]
    return [(f, args, {}) for f, args in parts] + [(atlas.card_atlas, (params,), {"own": own} if own else {})]


def ready(params: Params, own=None) -> bool:
    """Every part of the look of ``params`` is kept (writing it is quick)."""
    return all(part.known(*args, **keywords) for part, args, keywords in _parts(params, own))


def prepare(params: Params, own=None) -> None:
    """Work out every part of the look of ``params`` (kept for the writes that follow)."""
    for part, args, keywords in _parts(params, own):
        part(*args, **keywords)


class _Worker:
    """The one thread that works out looks asked for (``ask``)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None
        self.wanted: tuple | None = None  # (the settings, plants) asked for last, not yet taken
        self.after: threading.Event | None = None  # each part waits for it (``hold``)

    def ask(self, params: Params, own=None) -> None:
        with self.lock:
            self.wanted = (params, own)
            if self.thread is None:
                self.thread = threading.Thread(target=self._run, name="windgrass look", daemon=True)
                self.thread.start()

    def _run(self) -> None:
        while True:
            with self.lock:
                wanted, self.wanted = self.wanted, None
                if wanted is None:
                    self.thread = None
                    return
            try:
                for part, args, keywords in _parts(*wanted):
                    self._held()
                    part(*args, **keywords)
            except Exception:  # noqa: BLE001 (the bridge's own write works it out again and reports it)
                pass

    def _held(self) -> None:
        """Wait while ``hold``'s event is not set, at most HOLD_S (the event read again as it
        waits: a hold set, or moved to another event, once the look began applies)."""
        deadline = time.monotonic() + HOLD_S
        while (after := self.after) is not None and not after.is_set():
            left = deadline - time.monotonic()
            if left <= 0.0:
                return
            after.wait(min(left, HOLD_POLL_S))


_WORKER = _Worker()
HOLD_S = 10.0  # a part waits at most this long for ``hold``'s event
HOLD_POLL_S = 0.05  # ... looking again this often which event that is


def working() -> bool:
    """A look asked for is being worked out now (asking whether it is ready can wait)."""
    return _WORKER.thread is not None


def hold(until: threading.Event | None) -> None:
    """The parts of a look asked for wait until ``until`` is set (at most HOLD_S each; None: they
    do not wait): a new field's blocks, made on another thread, are not slowed by the look beside
    them (the two are numpy calls from Python, which share one lock of the interpreter)."""
    _WORKER.after = until


def ask(params: Params, own=None) -> bool:
    """True when the look of ``params`` (and the plants ``own``) is ready to write; else it is
    worked out on a thread (the settings asked for last first) and a later ``ask`` says when it is."""
    if ready(params, own):
        return True
    _WORKER.ask(params, own)
    return False
