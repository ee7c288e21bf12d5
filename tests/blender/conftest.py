"""Blender tests: every test starts from factory settings with the add-on loaded and registered.

``tests/conftest.py`` points Blender's user files at a temp dir before this imports bpy.
"""

import importlib

import bpy
import numpy as np
import pytest
from addon_loader import load_addon


@pytest.fixture(autouse=True)
def addon():
    """Factory settings (empty scene) and the registered add-on package ``windgrass``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    module = load_addon()
    if not hasattr(bpy.types.Scene, "windgrass"):  # something unregistered it behind our back
        module.unregister()
        module.register()
    yield module


@pytest.fixture
def scene():
    return bpy.context.scene


@pytest.fixture
def with_bridge(addon):
    """The add-on with its engine facade and bridge imported (an import error fails the test)."""
    for name in ("field", "bridge.scene", "bridge.runtime"):
        importlib.import_module(f"{addon.__name__}.grass_addon.{name}")
    return addon


@pytest.fixture
def drawn():
    """``drawn(item, role="blades")`` -> (vertices, 3) float64: what Blender draws of a field's
    role, read from the evaluated meshes of its slot objects in world space, in slot order (the
    engine's position order: each block's blades, each blade's joints, each joint's [left, right]);
    positions that show nothing are collapsed to one point."""

    def read(item, role="blades"):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        objects = sorted((o for o in item.collection.objects if o.get("wg_role") == role and o.type == "MESH"),
                         key=lambda o: int(o.get("wg_slot", -1)))
        parts = []
        for obj in objects:
            evaluated = obj.evaluated_get(depsgraph)
            co = np.empty(len(evaluated.data.vertices) * 3, np.float32)
            evaluated.data.vertices.foreach_get("co", co)
            m = np.array(evaluated.matrix_world, dtype=np.float64)
            parts.append(co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3])
        return np.concatenate(parts) if parts else np.zeros((0, 3))

    return read


@pytest.fixture
def rendered(with_bridge):
    """``rendered(params, frame, path)`` -> (height, width, 3) float32: the pixels Blender renders
    (row 0 at the bottom) of a factory scene staged as the batch renderer stages it, with a field
    of ``params`` and the camera posed at ``frame``, written to ``path`` and read back."""
    import stage
    from windgrass.grass_addon.bridge import properties, runtime

    def render(params, frame: int, path) -> np.ndarray:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        stage.setup_stage(scene, params)
        runtime.build_field(scene, properties.add_field(scene, params))
        stage.pose_camera(scene, params, frame)
        scene.frame_set(frame)
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(str(path))
        h, w = params.render.resolution_y, params.render.resolution_x
        pixels = np.array(image.pixels[:], dtype=np.float32).reshape(h, w, 4)[..., :3]
        bpy.data.images.remove(image)
        return pixels

    return render


@pytest.fixture
def runtime(with_bridge):
    """The bridge's runtime (the UI's one door)."""
    from windgrass.grass_addon.bridge import runtime

    return runtime


@pytest.fixture
def settle(runtime):
    """``settle()``: let edits made as in the panel settle (the runtime applies them once they stop)."""
    import time

    def wait() -> None:
        for _ in range(20):
            time.sleep(runtime.EDIT_SETTLE_S + 0.05)
            if runtime.flush_pending() is None:
                for scene in bpy.data.scenes:  # (and the work they started on threads)
                    for item in scene.windgrass.fields:
                        runtime.shown_when_done(scene, item)
                return
        raise AssertionError("the edits did not settle")

    return wait


@pytest.fixture
def stems(drawn):
    """``stems(item)`` -> (blades, joints, [left, right], 3) of the blades Blender draws (``drawn``;
    those collapsed onto their roots left out)."""

    def read(item) -> np.ndarray:
        n = item.blade.segments
        strips = drawn(item).reshape(-1, n + 1, 2, 3)
        return strips[np.ptp(strips.reshape(len(strips), -1, 3), axis=1).max(axis=1) > 0]

    return read


@pytest.fixture
def nearest_in_plane():
    """``nearest_in_plane(points, roots)`` -> for each point (n, 3) the index of the root (m, 3)
    nearest it in the ground plane, among the roots within 1 mm of it in x (the roots sorted by x: a
    few candidates a point, not every pair of 30,000)."""

    def nearest(points: np.ndarray, roots: np.ndarray, reach: float = 1e-3) -> np.ndarray:
        order = np.argsort(roots[:, 0], kind="stable")
        xs = roots[order, 0]
        first = np.searchsorted(xs, points[:, 0] - reach)
        count = np.searchsorted(xs, points[:, 0] + reach, side="right") - first
        best, best_d = np.zeros(len(points), np.int64), np.full(len(points), np.inf)
        for k in range(int(count.max(initial=0))):
            idx = order[np.minimum(first + k, len(xs) - 1)]
            d = ((points[:, :2] - roots[idx, :2]) ** 2).sum(axis=1)
            better = (k < count) & (d < best_d)
            best[better], best_d[better] = idx[better], d[better]
        return best

    return nearest


class _Parts:
    """What the heads' modifier draws of a field besides its strips, by species: ``objects(item,
    role)`` -> {species name: its object} (role "head" or "leaves": the objects in no scene it
    instances) and ``instances(item, role)`` -> {species name: (n, 4, 4) world matrices} of the
    instances of them the evaluated depsgraph holds now."""

    @staticmethod
    def objects(item, role: str) -> dict:
        from windgrass.grass_addon.bridge import owned

        rows = list(item.blade.species)
        return {rows[int(o["wg_slot"])].name: o for o in owned.registered(item).values()
                if isinstance(o, bpy.types.Object) and o.get("wg_role") == role}

    @staticmethod
    def instances(item, role: str) -> dict:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        by_mesh = {obj.data.name: name for name, obj in _Parts.objects(item, role).items()}
        out: dict = {name: [] for name in by_mesh.values()}
        for inst in depsgraph.object_instances:
            if inst.is_instance and inst.object.type == "MESH" and inst.object.data.name in by_mesh:
                out[by_mesh[inst.object.data.name]].append(np.array(inst.matrix_world, dtype=np.float64))
        return {name: np.array(m).reshape(-1, 4, 4) for name, m in out.items()}


@pytest.fixture
def parts(with_bridge):
    """``parts.objects(item, role)``, ``parts.instances(item, role)``: see ``_Parts``."""
    return _Parts
