"""Files last: a .blend saved by an earlier Windgrass opens with its grass as it was.

``tests/data/field-vN.blend`` was saved by Windgrass at settings version N (``make_saved_field.py``,
one file a version: 1 before LOD by screen size, the gust waves' stretch and the flowers' drifts, 2
with them) with what its blades drew at the frame it was saved at; opened here, the field draws
those vertices again, and its settings carry this version."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

DATA = Path(__file__).resolve().parent.parent / "data"


def _open(path: Path):
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    return bpy.context.scene


@pytest.mark.parametrize("version", [1, 2])
def test_a_file_of_each_settings_version_draws_its_grass_as_saved(with_bridge, drawn, tmp_path, version):
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime

    copy = tmp_path / f"field-v{version}.blend"
    copy.write_bytes((DATA / copy.name).read_bytes())  # (opened from a copy: the data stays as it is)
    scene = _open(copy)
    item = scene.windgrass.fields[0]
    scene.frame_set(int(scene["wg_drawn_frame"]))
    assert runtime.field_error(scene, item) is None
    want = np.array(scene["wg_drawn_at_save"], dtype=np.float64).reshape(-1, 3)
    got = drawn(item, "blades")[::53]
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    assert item[properties.SETTINGS_VERSION_KEY] == schema.SETTINGS_VERSION


def test_a_file_of_a_newer_windgrass_says_so(with_bridge, tmp_path, capsys):
    from windgrass.grass_addon.bridge import properties

    copy = tmp_path / "newer.blend"
    copy.write_bytes((DATA / "field-v1.blend").read_bytes())
    scene = _open(copy)
    scene.windgrass.fields[0][properties.SETTINGS_VERSION_KEY] = 99
    bpy.ops.wm.save_mainfile()
    _open(copy)
    out = capsys.readouterr().out
    assert "saved by a newer Windgrass (settings version 99" in out
