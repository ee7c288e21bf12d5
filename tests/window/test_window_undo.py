"""Undo and redo in a real Blender window: the sequences that crashed Blender or left stale grass.

Each check (driver.fields_ok) asks, for every field: its objects were built for its settings now,
the engine runs the settings now, no error is shown, and grass is drawn (slot vertices away from
the origin). Ctrl+Z and Ctrl+Shift+Z are typed over the 3D view, so Blender's own keymap runs
its undo after the undo steps the window pushed for each operator and each edit.
"""

from scenarios import fuzz_steps

CHECK = [{"frame": 1}, {"check": "fields"}]


def test_undo_after_preset_and_typed_edit_does_not_crash(real_blender):
    """Issue: Add > Grass Field (nothing selected), Species Preset > Meadow, Blades per cell 2 -> 4,
    Ctrl+Z: Blender segfaulted in its undo code (the settled edit rebuilt the objects between undo
    steps)."""
    steps = [{"select": None}, {"op": "windgrass.field_add"}, *CHECK,
             {"op": "windgrass.species_preset", "args": {"preset": "meadow"}}, *CHECK,
             {"set": "windgrass.fields[0].field.blades_per_cell", "value": 4}, *CHECK,
             {"key": "ctrl+z"}, *CHECK,
             {"python": "result = bpy.context.scene.windgrass.fields[0].field.blades_per_cell"},
             {"key": "ctrl+z"}, *CHECK,
             {"key": "ctrl+shift+z"}, {"key": "ctrl+shift+z"}, *CHECK,
             {"python": "result = bpy.context.scene.windgrass.fields[0].field.blades_per_cell"}]
    run = real_blender.run(steps)
    run.assert_clean()
    assert run.results("python") == [2, 4]  # undone to 2, redone to 4
    checks = [r for r in run.results("check")]
    assert all(field["vertices_shown"] > 0 for check in checks for field in check["fields"])


def test_undo_restores_the_grass_of_the_earlier_settings(real_blender):
    """Issue: Blades per cell 2 -> 4, Seed -> 3, Ctrl+Z: the settings were undone but the meshes
    kept the other layout, then the grass vanished ("press Rebuild")."""
    steps = [{"select": None}, {"op": "windgrass.field_add", "args": {"blocks_x": 4, "blocks_y": 4}}, *CHECK,
             {"set": "windgrass.fields[0].field.blades_per_cell", "value": 4}, *CHECK,
             {"set": "windgrass.fields[0].field.seed", "value": 3}, *CHECK,
             {"key": "ctrl+z"}, *CHECK, {"key": "ctrl+z"}, *CHECK, {"key": "ctrl+z"}, *CHECK,
             {"python": "f = bpy.context.scene.windgrass.fields\nresult = len(f)"},
             {"key": "ctrl+shift+z"}, *CHECK, {"key": "ctrl+shift+z"}, *CHECK, {"key": "ctrl+shift+z"}, *CHECK,
             {"python": "f = bpy.context.scene.windgrass.fields[0].field\nresult = [f.blades_per_cell, f.seed]"}]
    run = real_blender.run(steps)
    run.assert_clean()
    assert run.results("python") == [0, [4, 3]]  # three undos remove the field, three redos bring all back


def test_undo_redo_fuzz_in_the_window(real_blender):
    """Random sequences of Add, presets, edits, Rebuild, Remove, Ctrl+Z and Ctrl+Shift+Z, with a
    frame change and a check after each."""
    for seed in (1, 2):
        run = real_blender.run(fuzz_steps(seed, 30, keys=True), timeout=600, name=f"fuzz{seed}")
        run.assert_clean()
        assert len(run.results("check")) == 30
