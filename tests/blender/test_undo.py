"""Undo and redo in the bpy module: the settings, the objects and the engine of every field agree
after any number of steps, and its grass is drawn (``tests/window/driver.py`` checks; the same
scenarios run in a real Blender window in ``tests/window``)."""

import sys
from pathlib import Path

import bpy

WINDOW_TESTS = Path(__file__).resolve().parents[1] / "window"
if str(WINDOW_TESTS) not in sys.path:
    sys.path.insert(0, str(WINDOW_TESTS))

from driver import Driver  # noqa: E402
from scenarios import fuzz_steps  # noqa: E402

CHECK = [{"frame": 1}, {"check": "fields"}]


def _run(steps):
    bpy.ops.ed.undo_push(message="start")
    report = Driver(steps).run_background()
    problems = [f"{s['step']}: {s.get('exception') or s['result']['problems']}" for s in report["steps"]
                if "exception" in s or (isinstance(s.get("result"), dict) and s["result"].get("problems"))]
    assert not problems, "\n".join(problems)
    return report


def test_undo_restores_the_grass_of_the_earlier_settings(addon):
    """Issue: undo_push after Add, after the preset and after the edit, then undo and frame_set:
    "field 'Grass' cannot be simulated, its grass is hidden"."""
    steps = [{"op": "windgrass.field_add", "args": {"blocks_x": 4, "blocks_y": 4}}, *CHECK,
             {"op": "windgrass.species_preset", "args": {"preset": "meadow"}}, *CHECK,
             {"set": "windgrass.fields[0].field.blades_per_cell", "value": 4}, *CHECK,
             {"set": "windgrass.fields[0].field.seed", "value": 3}, *CHECK,
             {"undo": 1}, *CHECK, {"python": "result = bpy.context.scene.windgrass.fields[0].field.seed"},
             {"undo": 1}, *CHECK,
             {"python": "f = bpy.context.scene.windgrass.fields[0].field\nresult = [f.blades_per_cell, f.seed]"},
             {"redo": 2}, *CHECK,
             {"python": "f = bpy.context.scene.windgrass.fields[0].field\nresult = [f.blades_per_cell, f.seed]"}]
    report = _run(steps)
    python = [s["result"] for s in report["steps"] if "python" in s["step"]]
    assert python == [0, [2, 0], [4, 3]]
    checks = [s["result"]["fields"][0] for s in report["steps"] if "check" in s["step"]]
    assert all(c["vertices_shown"] > 0 and c["topology_matches"] and c["runtime_matches"] for c in checks)


def test_undo_redo_fuzz(addon):
    """Random sequences of Add, presets, edits, Rebuild, Remove, undo and redo, with a frame
    change and a check after each; most steps act on a field (few are skipped)."""
    for seed in range(3):
        report = _run(fuzz_steps(seed, 40, keys=False))
        acted = [s for s in report["steps"] if "check" not in s["step"] and "frame" not in s["step"]]
        skipped = [s for s in acted if "skipped" in s]
        assert len(skipped) <= len(acted) // 3, skipped
