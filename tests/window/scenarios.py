"""Scenarios for ``driver.py`` that the window tests and the bpy-module tests share (no bpy here)."""

from __future__ import annotations

import numpy as np


def fuzz_steps(seed: int, count: int, keys: bool, paint: bool = False) -> list[dict]:
    """A random sequence of what an artist does to a field (add, duplicate, presets, edits, rebuild,
    remove, undo, redo), each followed by a frame change and a check. ``keys``: undo and redo as typed
    keys (the window) instead of operators."""
    rng = np.random.default_rng(seed)
    edits = [("field.blades_per_cell", [1, 2, 3, 4]), ("field.seed", [0, 1, 2, 3]),
             ("blade.segments", [3, 4, 5, 6]), ("wind.speed", [1.0, 3.0, 6.0]), ("lod.card_far", [20.0, 30.0, 40.0]),
             ("field.blocks_x", [2, 3, 4]), ("field.cells_per_block", [8, 16])]
    if paint:  # what led to the crash on Ctrl+Z after a failed Rebuild (a source needing a terrain)
        edits += [("paint.length", ["", "vertex_group:path"]), ("keep_out.margin", [0.0, 0.5]),
                  ("paint.density", ["", "vertex_group:path"])]
    steps: list[dict] = [{"select": None}, {"op": "windgrass.field_add", "args": {"blocks_x": 3, "blocks_y": 3}}]
    for _ in range(count):
        roll = rng.random()
        if roll < 0.35:
            name, values = edits[rng.integers(len(edits))]
            value = values[rng.integers(len(values))]
            steps.append({"set": f"windgrass.fields[0].{name}", "value": value})
        elif roll < 0.45:
            preset = ["lawn", "meadow", "wild"][rng.integers(3)]
            steps.append({"op": "windgrass.species_preset", "args": {"preset": preset}})
        elif roll < 0.5:
            wind = ["calm", "blast", "gentle_breeze"][rng.integers(3)]
            steps.append({"op": "windgrass.wind_preset", "args": {"type": wind}})
        elif roll < 0.55:
            steps.append({"op": "windgrass.field_rebuild"})
        elif roll < 0.58:
            steps.append({"op": "windgrass.field_add", "args": {"blocks_x": 2, "blocks_y": 2}})
        elif roll < 0.6:  # (the fifth duplicate of the first of four fields crashed Blender: issue #37)
            steps.append({"op": "windgrass.field_duplicate"})
        elif roll < 0.63:
            steps.append({"op": "windgrass.field_remove"})
        elif roll < 0.85:
            steps.append({"key": "ctrl+z"} if keys else {"undo": 1})
        else:
            steps.append({"key": "ctrl+shift+z"} if keys else {"redo": 1})
        steps[-1]["optional"] = True
        steps.append({"frame": 1})
        steps.append({"check": "fields"})
    return steps
