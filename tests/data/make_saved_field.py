"""Make ``field-vN.blend`` (N: this Windgrass's settings version): a small field as Windgrass of
that version saves it, with what its blades drew at frame 12 (every 53rd vertex of Blender's
evaluated meshes, world space) kept in the scene's ``wg_drawn_at_save``.
``tests/blender/test_saved_files.py`` opens it and checks that this Windgrass draws the same. Run it
again only when a new settings version is made: it writes a new file beside the others
(``field-v3.blend``); the old files stay, each a promise kept.

    .venv/bin/python tests/data/make_saved_field.py
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent / "headless"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from addon_loader import load_addon  # noqa: E402
from mathutils import Vector  # noqa: E402

FRAME, EVERY = 12, 53


def drawn_sample(item) -> np.ndarray:
    depsgraph = bpy.context.evaluated_depsgraph_get()
    parts = []
    for obj in sorted((o for o in item.collection.objects if o.get("wg_role") == "blades" and o.type == "MESH"),
                      key=lambda o: int(o.get("wg_slot", -1))):
        ev = obj.evaluated_get(depsgraph)
        co = np.empty(len(ev.data.vertices) * 3, np.float32)
        ev.data.vertices.foreach_get("co", co)
        m = np.array(ev.matrix_world, dtype=np.float64)
        parts.append(co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3])
    return np.concatenate(parts)[::EVERY]


def main() -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon = load_addon()
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (-1.6, -1.2, 0.8)
    cam.rotation_euler = (Vector((0.4, 0.3, 0.1)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.windgrass.field_add(blocks_x=4, blocks_y=4)
    item = scene.windgrass.fields[0]
    item.wind.speed = 7.0
    scene.frame_set(FRAME)
    scene["wg_drawn_at_save"] = drawn_sample(item).ravel().tolist()
    scene["wg_drawn_frame"] = FRAME
    version = sys.modules[addon.__name__ + ".grass_addon.schema"].SETTINGS_VERSION
    bpy.ops.wm.save_as_mainfile(filepath=str(HERE / f"field-v{version}.blend"), compress=True)


if __name__ == "__main__":
    main()
