"""A wind that loops (``simulation.loop``): frame k and frame k + loop x fps are the same bits, the
loop has no seam, and the looped wind is the same wind (its spread, its travel downwind)."""

import numpy as np
import pytest
from windgrass.grass_addon import loop, schema
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.field import GrassField
from windgrass.grass_addon.lod import Camera
from windgrass.grass_addon.wind import WindField

CAMERA = Camera.look_at((-1.2, -0.9, 0.6), (0.4, 0.2, 0.1), fov_x=1.0)


def params(loop_s: float, **more):
    values = {"field.blocks_x": 3, "field.blocks_y": 2, "field.cells_per_block": 4, "field.blades_per_cell": 2,
              "blade.segments": 4, "simulation.preroll": 1.0, "simulation.epoch": 1.5, "simulation.loop": loop_s,
              "wind.speed": 5.0, "wind.turbulence": 0.8, "wind.gust_waves": 0.6, "wind.gust_wave_size": 3.0,
              "lod.blade_near": 1.0, "lod.blade_far": 2.0, "lod.card_near": 2.5, "lod.card_far": 6.0}
    values.update(more)
    return schema.defaults().replace(values)


def drawn(field, frame, views=CAMERA):
    shown = field.frame(frame, 0.0, views)
    rows = [a.vertices[: a.count * a.shape.verts_per_block].copy() for a in (shown.blades, shown.cards)]
    return rows, shown.gust


@pytest.mark.parametrize("loop_s", [2.0, 5.0])
def test_a_frame_and_the_frame_one_loop_later_are_the_same_bits(loop_s):
    p = params(loop_s)
    period = loop.loop_frames(p)
    assert period == round(loop_s * 24)
    field = GrassField(p)
    assert all(len(rows) for rows in drawn(field, 1)[0]), "the camera sees blades and cards"
    for k in (1, 17, period - 1):
        first, gust = drawn(field, k)
        for later in (k + period, k + 3 * period):
            again, gust_again = drawn(field, later)
            for a, b in zip(first, again):
                np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(gust[0], gust_again[0])
            np.testing.assert_array_equal(gust[2], gust_again[2])
            assert gust[3] == gust_again[3]
    fresh = GrassField(p)  # (any way to the frame: a fresh field seeking it straight)
    for a, b in zip(drawn(fresh, 17 + 2 * period)[0], drawn(field, 17)[0]):
        np.testing.assert_array_equal(a, b)


def _far_shading(p, gust, points):
    """The far grass's gust brightness at ``points`` as its material computes it from a frame's
    ``gust`` (materials.gusted: 1 + sum of weight (2 g - 1) over the loop's two patterns)."""
    from windgrass.grass_addon import gusts

    tile, metres = gusts.pattern(int(p.field.seed), float(p.wind.direction)), gusts.tile_metres(p)
    shift, _, other, (a, b) = gust
    return 1.0 + a * (2.0 * gusts.sample(tile, points, metres, shift) - 1.0) + \
        b * (2.0 * gusts.sample(tile, points, metres, other) - 1.0)


def test_the_loop_has_no_seam():
    """Across the loop's end (frame P - 1 to P) the blades move, and the far grass's gust shading
    changes, no more than between neighbours inside the loop."""
    p = params(2.0)
    period = loop.loop_frames(p)
    field = GrassField(p)
    points = np.random.default_rng(5).uniform(-40.0, 40.0, (400, 2))
    tips, shading = [], []
    for f in range(1, period + 2):
        rows, gust = drawn(field, f, None)
        tips.append(rows[0])
        shading.append(_far_shading(p, gust, points))
    for series in (tips, shading):
        steps = [float(np.abs(b - a).max()) for a, b in zip(series, series[1:])]
        seam = steps[period - 1]  # frame P to P + 1: the first frame of the second loop
        assert seam <= 2.0 * float(np.median(steps)), (seam, np.median(steps))


def test_the_looped_wind_keeps_its_spread_and_travels_at_the_mean_wind():
    """The turbulence's spread over a large field at mid-loop (the two patterns weigh the same)
    is that of the wind without a loop, within 10 %; the mean wind carries the pattern as before."""
    big = {"field.blocks_x": 12, "field.blocks_y": 12, "field.cells_per_block": 16, "wind.gust_waves": 0.0}
    looped, plain = params(4.0, **big), params(0.0, **big)
    field = GrassField(plain)
    w_loop, w_plain = WindField(field.layout, looped), WindField(field.layout, plain)
    spreads = [(float(np.std(w_loop.sample(t)[:, 1])), float(np.std(w_plain.sample(t)[:, 1]))) for t in (1.0, 2.0, 3.0)]
    for a, b in spreads:
        assert a == pytest.approx(b, rel=0.1)
    np.testing.assert_allclose(w_loop.displacement(2.0), w_plain.displacement(2.0))


def test_a_loop_shorter_than_the_warm_up_is_refused_with_the_smallest_that_works():
    with pytest.raises(ParameterError) as err:
        params(0.6)
    assert err.value.key == "simulation.loop" and "at least 1 s" in str(err.value)


def test_what_breaks_the_loop_is_said():
    keyed = params(2.0, **{"wind.keys": ({"time": 0.0, "speed": 3.0, "direction": 0.0},
                                         {"time": 1.5, "speed": 6.0, "direction": 10.0})})
    notes = GrassField(keyed).loop_notes()
    assert len(notes) == 1 and "keyed" in notes[0]
    assert GrassField(params(2.0)).loop_notes() == []
    assert GrassField(params(0.0, **{"wind.keys": keyed.wind.keys})).loop_notes() == []
