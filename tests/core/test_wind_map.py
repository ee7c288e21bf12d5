"""The wind the grass feels, on a grid (``wind_map.py``): what Blender's Hair and Cloth Dynamics blow
with (``bridge/wind_force.py``; ``tests/blender/test_wind_force.py`` checks hair in Blender)."""

import math

import numpy as np
from windgrass.grass_addon import schema, wind_map
from windgrass.grass_addon.field import GrassField


def _blast(**values):
    base = {"field.blocks_x": 16, "field.blocks_y": 2, "field.cells_per_block": 8, "field.blades_per_cell": 1,
            "blade.segments": 3, "simulation.preroll": 0.5, "wind.type": "blast", "wind.speed": 1.0,
            "wind.direction": 0.0, "wind.turbulence": 0.0, "wind.gust_speed": 8.0, "wind.gust_width": 2.0,
            "wind.gust_interval": 60.0}
    base.update(values)
    return schema.defaults().replace(base)


def test_the_grid_covers_the_field_and_a_spacing_beyond_with_faces_looking_up():
    """A 20 x 1.6 m field: the grid reaches one spacing past every edge, at most 64 points a
    side, a spacing of 20 / 61 m (a 0.5 m field's is the least, 0.25 m); each quad winds
    counter-clockwise seen from above."""
    grid = wind_map.map_grid((-10.0, -0.8, 10.0, 0.8))
    pts = grid.points()
    assert grid.nx <= wind_map.MAX_SIDE and math.isclose(grid.spacing, 20.0 / 61)
    assert pts[:, 0].min() < -10 and pts[:, 0].max() > 10 and pts[:, 1].min() < -0.8 and pts[:, 1].max() > 0.8
    assert pts[:, 0].max() - 10 <= grid.spacing + 1e-9
    corners = pts[grid.quads()]
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert (cross > 0).all()
    small = wind_map.map_grid((0.0, 0.0, 0.5, 0.5))
    assert small.spacing == wind_map.MIN_SPACING


def test_the_map_carries_the_gust_front_where_the_blast_puts_it():
    """A blast's front (8 m/s, 2 m wide) in a calm 1 m/s runs downwind at 1 + 8 / 2 = 5 m/s from
    3 widths before the field's upwind edge (-6.4 m): at t = 2 s it is at -12.4 + 10 = -2.4 m.
    The map's wind peaks there (within a grid spacing) at 1 + 8 m/s along +X, and is the calm
    1 m/s far from it."""
    field = GrassField(_blast())
    frame = 1 + 2 * field.clock.rate  # t = 2 s
    grid, wind = field.wind_map(frame)
    x = grid.points()[: grid.nx, 0]
    row = wind.reshape(grid.ny, grid.nx, 2)[grid.ny // 2]
    peak = int(np.argmax(row[:, 0]))
    assert abs(x[peak] - (-2.4)) <= grid.spacing
    assert abs(row[peak, 0] - 9.0) < 0.4 and np.abs(row[:, 1]).max() < 1e-4
    far = np.abs(x - (-2.4)) > 8.0
    np.testing.assert_allclose(row[far, 0], 1.0, atol=0.01)


def test_the_map_is_the_wind_the_solver_steps_the_cells_with():
    """Where a grid point falls on a cell's centre, the map's wind is the cell's (the same
    sampler, the same instant): checked on a turbulent breeze at points placed on cell centres."""
    field = GrassField(_blast(**{"wind.type": "moderate_breeze", "wind.turbulence": 1.5}))
    field.seek(7)
    cells = field.layout.cell_center[:40]
    points = np.column_stack([cells, np.zeros(len(cells))])
    np.testing.assert_allclose(field.sim.wind_at(7, points), field.sim.cell_wind[:40], atol=1e-5)


def test_the_drag_is_quadratic_in_the_air_speed_past_the_point():
    """F = drag |u| u, u = wind - velocity: 0.002 kg/m in 5 m/s on a point at rest is 0.05 N
    downwind; a point moving with the air feels nothing; one moving 1 m/s against a 3 m/s wind
    feels the drag of 4 m/s."""
    wind = np.array([[5.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    velocity = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    force = wind_map.drag_force(wind, velocity, 0.002)
    np.testing.assert_allclose(force, [[0.05, 0, 0], [0, 0, 0], [0.032, 0, 0]], atol=1e-12)
