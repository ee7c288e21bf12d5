"""Output folders: created and proven writable before long work starts (stdlib only)."""

from __future__ import annotations

import tempfile
from pathlib import Path


def ensure_writable(folder: Path, create: bool = True) -> None:
    """Raise OSError unless a new file can be made in ``folder`` (created first when ``create``)."""
    if create:
        folder.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=folder, prefix=".windgrass-probe-"):
        pass


def user_folder(value, name: str) -> Path:
    """The folder a user named (``~`` expanded); ParameterError naming the setting ``name`` when
    the value is empty (an empty path would write into whatever the current folder is)."""
    from .errors import ParameterError

    text = str(value).strip() if value is not None else ""
    if not text:
        raise ParameterError(name, "no folder given (valid: a folder's path; it is created if missing)")
    if "\x00" in text:
        raise ParameterError(name, f"{text!r} holds a NUL character (valid: a folder's path)")
    try:
        return Path(text).expanduser()
    except RuntimeError as exc:  # ~user of no such user
        raise ParameterError(name, f"{text}: {exc} (valid: a folder's path, ~ for your own home folder)") from None
