"""Write ``grass_addon/params_typed.py`` again from the schema (after a parameter is added, renamed
or retyped): the sections' types mypy checks every read of a parameter with.

    python3.11 dev.py params
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

common.load()  # the engine as windgrass.grass_addon (numpy only, no Blender)
from windgrass.grass_addon import schema  # noqa: E402

TARGET = Path(__file__).resolve().parents[1] / "grass_addon" / "params_typed.py"

if __name__ == "__main__":
    TARGET.write_text(schema.typed_source())
    print(f"wrote {TARGET}")
