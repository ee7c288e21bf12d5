"""The field in the artist's own node trees (issue #60): Map for Node Trees puts the field's wind,
height, bend, flatness, tops and species on a grid on its ground, and the README's example tree
(docs/examples/stones_where_flat.py) scatters stones where a ball trampled the grass. Read from
what Blender evaluates: the map's attributes, the stones' mesh and the blades drawn beside them.

The field: 4 x 4 blocks of 8 cells of 0.1 m (3.2 m square), 4 blades a cell.
"""

from __future__ import annotations

import runpy
from pathlib import Path

import bpy
import numpy as np

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "stones_where_flat.py"


def _field(runtime, speed=0.0):
    from windgrass.grass_addon.bridge import properties

    assert bpy.ops.windgrass.field_add(blocks_x=4, blocks_y=4, cells_per_block=8, blades_per_cell=4,
                                       edge=0.0) == {"FINISHED"}
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 200
    item = scene.windgrass.fields[-1]
    with properties.batch(item):
        item.wind.speed = speed
        item.wind.turbulence = 0.0
        item.wind.direction = 0.0
        item.wind.gust_waves = 0.0  # (the Add menu's field has them: a steady wind here)
    return scene, item


def _ball():
    """A 0.3 m ball rolled along y = 0 from x = -1.2 m (frame 1) to 1.2 m (frame 25)."""
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, segments=32, ring_count=16)
    ball = bpy.context.active_object
    for frame, where in ((1, (-1.2, 0.0, 0.3)), (25, (1.2, 0.0, 0.3))):
        ball.location = where
        ball.keyframe_insert("location", frame=frame)
    coll = bpy.data.collections.new("Colliders")
    bpy.context.scene.collection.children.link(coll)
    coll.objects.link(ball)
    return coll


def _points(obj) -> np.ndarray:
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    co = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", co)
    return (co.reshape(-1, 3).astype(np.float64) @ np.array(obj.matrix_world)[:3, :3].T
            + np.array(obj.matrix_world)[:3, 3])


def _attribute(obj, name: str) -> np.ndarray:
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    attribute = mesh.attributes[name]
    width = 3 if attribute.data_type == "FLOAT_VECTOR" else 1
    out = np.empty(width * len(mesh.vertices), np.int32 if attribute.data_type == "INT" else np.float32)
    attribute.data.foreach_get("vector" if width == 3 else "value", out)
    return out.reshape(-1, 3) if width == 3 else out


def test_the_examples_stones_lie_where_the_ball_trampled_the_grass(runtime, stems):
    """Frame 30 (the ball stopped at x = 1.2 m at frame 25): the example's stones lie along the
    ball's path (0.6 m wide), on the ground, none out in the standing grass; the drawn blade
    nearest each stone lies flatter than the grass 1 m away (its median under 0.6 of theirs);
    8 s later the grass along the path stood up again (interaction.recovery 4 s): stones lie only
    under the ball, which rests at its last key."""
    scene, item = _field(runtime)
    item.collider_collection = _ball()
    scene.frame_set(30)
    stones = runpy.run_path(str(EXAMPLE), run_name="example")["main"]()
    scene.frame_set(30)
    at = _points(stones)
    assert len(at) > 100, "the trail holds stones"
    assert np.abs(at[:, 1]).max() < 0.45 and np.ptp(at[:, 0]) > 1.5, "along the ball's path, the whole of it"
    assert np.abs(at[:, 2]).max() < 0.1, "on the ground"
    blades = stems(item)
    roots, tips = blades[:, 0].mean(axis=1), blades[:, -1].mean(axis=1)
    height = tips[:, 2] - roots[:, 2]
    nearest = np.array([np.argmin(np.hypot(*(roots[:, :2] - xy).T)) for xy in at[::7, :2]])
    standing = np.abs(roots[:, 1]) > 1.0
    assert np.median(height[nearest]) < 0.6 * np.median(height[standing])
    scene.frame_set(30 + 8 * scene.render.fps)
    later = _points(stones)
    assert len(later) > 10 and np.hypot(later[:, 0] - 1.2, later[:, 1]).max() < 0.45, "only under the ball"


def test_the_map_reads_the_wind_and_the_grass_it_bends(runtime, stems):
    """In a steady 3 m/s wind along +X, the map's points lie on the ground and read wind (3, 0, 0)
    and wind_speed 3 over the grass; its bend is the grass's lean (a fifth of a radian at least,
    none in still air), its tips stand downwind of the points and below the grass's height, as
    the drawn blades' tips do; its species are the field's (the Add menu's mix: more than one); its
    height is that of the tallest blades drawn in still air (4 a cell: the 80th percentile of the
    blades' heights, within 10 %)."""
    scene, item = _field(runtime, speed=3.0)
    assert bpy.ops.windgrass.field_map_add() == {"FINISHED"}
    shared = runtime.wind_force.map_object(item)
    scene.frame_set(60)
    points = _points(shared)
    inside = (np.abs(points[:, 0]) < 1.4) & (np.abs(points[:, 1]) < 1.4)
    assert inside.sum() > 50 and np.abs(points[:, 2]).max() < 1e-6
    np.testing.assert_allclose(_attribute(shared, "wind")[inside], [[3.0, 0.0, 0.0]] * inside.sum(), atol=1e-3)
    np.testing.assert_allclose(_attribute(shared, "wind_speed")[inside], 3.0, atol=1e-3)
    bend, tip, height = (_attribute(shared, n)[inside] for n in ("bend", "tip", "height"))
    lean = tip[:, 0] - points[inside, 0]
    assert bend.min() > 0.2 and lean.min() > 0.02 and (tip[:, 2] < height).all()
    blades = stems(item)
    drawn_lean = blades[:, -1].mean(axis=1)[:, 0] - blades[:, 0].mean(axis=1)[:, 0]
    assert np.median(drawn_lean) > 0.02
    species = _attribute(shared, "species")[inside]
    assert species.min() >= 0 and species.max() < len(item.blade.species) and len(np.unique(species)) > 1
    from windgrass.grass_addon.bridge import properties

    with properties.batch(item):
        item.wind.speed = 0.0
    scene.frame_set(61)
    assert np.abs(_attribute(shared, "bend")[inside]).max() < 0.02
    blades = stems(item)
    tallest = np.percentile(blades[:, -1, :, 2].max(axis=1) - blades[:, 0, :, 2].min(axis=1), 80)
    grass = np.median(_attribute(shared, "height")[inside])
    assert abs(grass - tallest) < 0.1 * tallest, (grass, tallest)
