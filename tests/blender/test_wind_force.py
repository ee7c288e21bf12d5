"""One wind for Blender's own physics (issue #60): hair simulated by Blender's Hair Dynamics (5.2+)
blows in the meadow's wind. Everything is read from what Blender evaluates: the hair curves' points
after Blender's own XPBD solver stepped them, and the blades of the evaluated slot meshes."""

import bpy
import numpy as np
import pytest

FPS = 24
SPACING = 6.0  # m between the two tufts, along the wind
GUST_SPEED, MEAN = 8.0, 1.0  # m/s: a blast's front runs downwind at MEAN + GUST_SPEED / 2 (wind.gust_fronts)

needs_52 = pytest.mark.skipif(bpy.app.version < (5, 2, 0), reason="Hair Dynamics is Blender 5.2's")


def _blast_field(scene):
    """A 12.8 x 3.2 m field (every blade drawn) in a blast: a calm 1 m/s with one gust front of
    8 m/s, 2 m wide, crossing it towards +X; no turbulence, so the front is all that moves the air."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties, runtime

    params = schema.defaults().replace({
        "field.blocks_x": 16, "field.blocks_y": 4, "field.cells_per_block": 8, "field.blades_per_cell": 2,
        "wind.type": "blast", "wind.speed": MEAN, "wind.direction": 0.0, "wind.turbulence": 0.0,
        "wind.gust_speed": GUST_SPEED, "wind.gust_width": 2.0, "wind.gust_interval": 60.0, "lod.enabled": False,
        "render.fps": FPS, "render.frame_end": 100})
    scene.render.fps, scene.frame_start, scene.frame_end = FPS, 1, 100
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    return item


def _hair(scene, roots, height: float = 0.5, points: int = 8):
    """A hair curves object of upright strands at ``roots`` (x, y) with Blender's Hair Dynamics
    asset as its modifier (as Add Modifier > Physics > Hair Dynamics makes it), in physics mode,
    without gravity (the strands stand; only a force bends them)."""
    import os

    path = os.path.join(bpy.utils.system_resource("DATAFILES"), "assets", "nodes",
                        "geometry_nodes_dynamics_assets.blend")
    with bpy.data.libraries.load(path, link=False) as (_, into):
        into.node_groups = ["Hair Dynamics"]
    dynamics = into.node_groups[0]
    curves = bpy.data.hair_curves.new("tufts")
    curves.add_curves([points] * len(roots))
    pos = np.zeros((len(roots), points, 3), np.float32)
    pos[:, :, :2] = np.asarray(roots, np.float32)[:, None, :]
    pos[:, :, 2] = np.linspace(0.0, height, points)[None]
    curves.position_data.foreach_set("vector", pos.ravel())
    obj = bpy.data.objects.new("tufts", curves)
    scene.collection.objects.link(obj)
    mod = obj.modifiers.new("Hair Dynamics", "NODES")
    mod.node_group = dynamics
    inputs = {i.name: i.identifier for i in dynamics.interface.items_tree
              if i.item_type == "SOCKET" and i.in_out == "INPUT" and i.socket_type != "NodeSocketVector"}
    getattr(mod.properties.inputs, inputs["Mode"]).value = "Physics (Experimental)"
    getattr(mod.properties.inputs, inputs["Gravity"]).value = False
    return obj, pos


def _hair_points(obj, shape) -> np.ndarray:
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    p = np.empty(int(np.prod(shape)), np.float32)
    evaluated.data.position_data.foreach_get("vector", p)
    return p.reshape(shape).astype(np.float64)


def _rise(series: np.ndarray) -> float:
    """The time (s) a deflection first climbs half way from its calm start to its peak."""
    calm = series[:8].mean()
    half = calm + 0.5 * (series.max() - calm)
    i = int(np.argmax(series > half))
    return (i - 1 + (half - series[i - 1]) / (series[i] - series[i - 1])) / FPS


@needs_52
def test_a_gust_front_reaches_the_hair_when_it_reaches_the_grass_beside_it(stems):
    """Two tufts of hair 6 m apart along the wind stand in the meadow; Blow Hair and Cloth (the
    Wind panel's button, the tufts' object active) makes the field's wind their Hair Dynamics'
    effector. As the gust front runs down the field, each tuft bends downwind as the grass round
    it bends: the hair's deflection rises within 0.3 s of the grass's beside it, the front
    reaches the second tuft (hair and grass) 6 m / (1 + 8 / 2) m/s = 1.2 s after the first
    (within 0.15 s), the hair bends downwind (+X, several centimetres, hardly sideways), and
    before the front comes the hair stands still (the calm 1 m/s bends it less than a fifth as
    much)."""
    scene = bpy.context.scene
    item = _blast_field(scene)
    roots = [(x, y) for x in (-0.5 * SPACING, 0.5 * SPACING) for y in (-0.1, 0.0, 0.1)]
    hair, rest = _hair(scene, roots)
    bpy.context.view_layer.objects.active = hair
    scene.frame_set(1)
    assert bpy.ops.windgrass.wind_force_add() == {"FINISHED"}
    mod = hair.modifiers["Hair Dynamics"]
    ident = next(i.identifier for i in mod.node_group.interface.items_tree
                 if i.item_type == "SOCKET" and i.name == "Effectors Collection")
    assert getattr(mod.properties.inputs, ident).value == bpy.data.collections["Windgrass Wind"]
    n = item.blade.segments
    hair_dx, hair_dy, grass_dx = [], [], []
    for frame in range(1, 101):
        scene.frame_set(frame)
        tips = _hair_points(hair, rest.shape)[:, -1]
        bend = tips - rest[:, -1]
        hair_dx.append([bend[:3, 0].mean(), bend[3:, 0].mean()])
        hair_dy.append(np.abs(bend[:, 1]).max())
        centre = stems(item).mean(axis=2)
        lean = centre[:, n, 0] - centre[:, 0, 0]
        grass_dx.append([lean[np.hypot(centre[:, 0, 0] - x, centre[:, 0, 1]) < 0.5].mean()
                         for x in (-0.5 * SPACING, 0.5 * SPACING)])
    hair_dx, grass_dx = np.array(hair_dx), np.array(grass_dx)
    expected = SPACING / (MEAN + 0.5 * GUST_SPEED)
    hair_at = [_rise(hair_dx[:, k]) for k in (0, 1)]
    grass_at = [_rise(grass_dx[:, k]) for k in (0, 1)]
    for k in (0, 1):
        assert abs(hair_at[k] - grass_at[k]) < 0.3, (k, hair_at, grass_at)
        assert hair_dx[:, k].max() > 0.03, hair_dx[:, k].max()
        assert hair_dx[:8, k].max() < 0.2 * hair_dx[:, k].max(), hair_dx[:8, k]
    assert abs((hair_at[1] - hair_at[0]) - expected) < 0.15, (hair_at, expected)
    assert abs((grass_at[1] - grass_at[0]) - expected) < 0.15, (grass_at, expected)
    assert max(hair_dy) < 0.1 * hair_dx.max(), max(hair_dy)
    winds = bpy.data.collections["Windgrass Wind"]
    assert len(winds.objects) == 1
    assert bpy.ops.windgrass.field_remove() == {"FINISHED"}
    assert len(winds.objects) == 0 and not [o for o in bpy.data.objects if o.get("wg_role") == "wind_map"]


@pytest.mark.skipif(bpy.app.version >= (5, 2, 0), reason="before 5.2 Blender has no Hair Dynamics")
def test_before_blender_5_2_blow_hair_and_cloth_says_what_it_needs(runtime):
    """Blender 4.5 has no Geometry Nodes hair or cloth physics: the operator refuses with a
    sentence naming the version it needs, and makes nothing."""
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    objects = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match=r"needs Blender 5\.2 or newer"):
        bpy.ops.windgrass.wind_force_add()
    assert len(bpy.data.objects) == objects and "Windgrass Wind" not in bpy.data.collections
    assert "needs Blender 5.2" in runtime.wind_force.needs_note()
