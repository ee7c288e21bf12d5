"""The one thread pool of the engine, shared by the solver and the kinematics.

numpy releases the GIL inside its loops, so two lanes of long numpy calls run in parallel. Work
is split so that every output element is written by exactly one lane: results never depend on
the threading. Lane 0 runs in the calling thread; the others on the pool.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

THREADS = 2  # lanes: the machines this runs on have two or more cores

_POOL: ThreadPoolExecutor | None = None
_LOCK = threading.Lock()


def pool() -> ThreadPoolExecutor:
    """The shared pool (THREADS - 1 workers; the caller is the other lane), made on first use."""
    global _POOL
    with _LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=max(1, THREADS - 1), thread_name_prefix="windgrass")
        return _POOL


def run_lanes(work: Callable[[int], None], lanes: int) -> None:
    """Run ``work(0) .. work(lanes - 1)`` in parallel and wait; a lane's error is raised here.
    No lanes (nothing to do: an empty window of cells) runs nothing."""
    if lanes <= 0:
        return
    if lanes <= 1:
        work(0)
        return
    futures = [pool().submit(work, lane) for lane in range(1, lanes)]
    try:
        work(0)
    finally:
        for future in futures:
            future.result()
