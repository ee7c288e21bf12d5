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
