"""A clean process exit when Blender runs as the ``bpy`` Python module (Blender 4.2-4.5).

Those module builds free their editor types from C++ static destructors that run after Python
has shut down. Any Python class or function still known to Blender at that point (registered
panels, operators, property callbacks, ``bpy.app.handlers`` entries) is released there through
a Python API that no longer exists: the process segfaults (4.2) or hangs (4.5) after its work is
done, even when everything was unregistered. Blender 5.0 frees them while Python still runs.

The guard registers libc's ``_exit`` with glibc's ``on_exit``, then ``fcloseall``.
C exit handlers run last-registered first, so at ``exit`` the C streams are flushed (Blender's own
shutdown messages included), then ``_exit`` ends the process, before those destructors, with the
exit status Python chose (``on_exit`` passes it as the first argument). Python has run its
``atexit`` functions (Blender's shutdown among them) and flushed its streams by then. Only for the
module (a Blender executable exits by itself), only before 5.0, only on Linux (glibc).
"""

from __future__ import annotations

import atexit
import ctypes
import sys

import bpy

_guarded = False


def needs_guard() -> bool:
    """True in a ``bpy`` module process of Blender < 5.0 on glibc Linux."""
    return (not bpy.app.binary_path and bpy.app.version < (5, 0, 0)
            and sys.platform.startswith("linux"))


def guard() -> bool:
    """Arrange the clean exit once per process; returns whether it is arranged."""
    global _guarded
    if _guarded or not needs_guard():
        return _guarded
    try:
        libc = ctypes.CDLL(None)
        libc.on_exit, libc._exit, libc.fcloseall  # noqa: B018 (glibc only)
    except (OSError, AttributeError):  # not glibc: nothing to hook into
        return False
    # Blender creates some of those static objects lazily (on first render, say), after this
    # point; C exit handlers registered now would run after their destructors. So the C handlers
    # are registered at Python's own exit, when every such object exists.
    atexit.register(_register_c_handlers, libc)
    _guarded = True
    return True


def _register_c_handlers(libc) -> None:
    libc.on_exit(libc._exit, None)  # _exit(status)
    libc.on_exit(libc.fcloseall, None)  # runs first: flush every C stream

def register() -> None:
    guard()  # once per process; there is nothing to undo on unregister
