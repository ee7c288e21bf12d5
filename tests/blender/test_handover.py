"""Issue #60: the blade strips written whole against strips Geometry Nodes build from the joints
(``headless/bench_handover.py``, whose figures decided that the strips stay written whole). The
trees the benchmark times must draw what the engine draws, on every Blender line, or its figures
would compare unlike things: here the strips Blender evaluates from the joints are the engine's, and
the cards it evaluates from a point per card are the engine's, with their opacity."""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_the_strips_and_cards_geometry_nodes_build_are_the_engines():
    env = {**os.environ, "BLENDER_USER_RESOURCES": tempfile.mkdtemp(prefix="windgrass-handover-")}
    command = [sys.executable, str(REPO / "headless" / "bench_handover.py"), "--blades", "1000", "--frames", "2",
               "--cards-m", "12.8", "--json"]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    run = result["runs"][0]
    segments = 5  # (the schema's default: 6 joints, a strip of 12 vertices)
    for way in ("strips", "gn_extrude", "gn_sample"):
        drawn = run[way]
        assert drawn["evaluated_vertices"] == run["blades"] * 2 * (segments + 1), (way, drawn)
        assert drawn["max_error_m"] < 1e-5, (way, drawn["max_error_m"])  # float32 rounding of 0.1-1 m
    assert run["strips"]["bytes_per_blade"] == 2 * (segments + 1) * 12
    assert run["gn_sample"]["bytes_per_blade"] == run["gn_extrude"]["bytes_per_blade"] == (segments + 1) * 16
    cards = result["cards"]
    assert cards["cards"]["cards"] == cards["cards_gn"]["cards"] > 1000  # (a 12.8 m field's, beyond its blades)
    for way in ("cards", "cards_gn"):
        drawn = cards[way]
        assert drawn["evaluated_vertices"] == 4 * drawn["cards"], (way, drawn)
        assert drawn["max_error_m"] < 1e-5 and drawn["max_fade_error"] < 1e-6, (way, drawn)
    assert cards["cards"]["bytes_per_card"] == 80 and cards["cards_gn"]["bytes_per_card"] == 20
