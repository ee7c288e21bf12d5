"""Wind field (paper IV, eqs 12-13): mean wind keys, smoothed turbulence, blast and whirlwind.

Expected numbers come from physics and from the 1 2 1 / 2 4 2 / 1 2 1 filter of eq 13, never
from the code's own output.
"""

import math

import numpy as np
import pytest
from windgrass.grass_addon import gusts, schema
from windgrass.grass_addon.errors import ParameterError
from windgrass.grass_addon.layout import build_layout
from windgrass.grass_addon.wind import WindField

# 1-D [1, 2, 1] / 4 filter of eq 13 applied to white noise: correlation at lag 0, 1, 2, 3.
# (sum of products of the shifted kernel over sum of squares: 6/6, 4/6, 1/6, 0).
KERNEL_CORR_1D = (1.0, 2.0 / 3.0, 1.0 / 6.0, 0.0)
# Sum of squared correlations of the 2-D field over all lags: (1 + 2 (2/3)^2 + 2 (1/6)^2)^2.
SUM_RHO2 = (1.0 + 2 * (2 / 3) ** 2 + 2 * (1 / 6) ** 2) ** 2


def make(blocks=(2, 2), cells_per_block=8, cell_size=0.1, wind_keys=None, seed=0, **wind):
    """A small field and its wind; ``wind`` holds wind.* overrides (``speed=0``...)."""
    params = schema.defaults().replace({
        "field.blocks_x": blocks[0], "field.blocks_y": blocks[1],
        "field.cells_per_block": cells_per_block, "field.cell_size": cell_size,
        "field.blades_per_cell": 1, "field.seed": seed, **{f"wind.{k}": v for k, v in wind.items()}})
    layout = build_layout(params)
    return layout, WindField(layout, params, keys=wind_keys)


def grid(layout, v):
    """(n_cells, 2) -> (cells_y, cells_x, 2)."""
    return v.reshape(layout.cells_y, layout.cells_x, 2)


def cell_at(layout, x, y):
    return int(np.argmin(np.hypot(layout.cell_center[:, 0] - x, layout.cell_center[:, 1] - y)))


def corr(a, b):
    a, b = a.ravel() - a.mean(), b.ravel() - b.mean()
    return float(np.dot(a, b) / math.sqrt(np.dot(a, a) * np.dot(b, b)))


# ---------------------------------------------------------------------------------- mean wind


def test_constant_mean_from_params():
    _, wind = make(speed=3.0, direction=120.0, turbulence=0.0)
    for t in (-2.0, 0.0, 7.5):
        speed, direction = wind.mean(t)
        assert speed == pytest.approx(3.0)
        assert direction == pytest.approx(math.radians(120.0))
    v = wind.sample(1.0)
    expected = 3.0 * np.array([math.cos(math.radians(120)), math.sin(math.radians(120))])
    np.testing.assert_allclose(v, np.broadcast_to(expected, v.shape), atol=1e-5)


def test_mean_follows_keys_linearly_and_is_continuous():
    _, wind = make(wind_keys=[(0.0, 2.0, 0.0), (10.0, 6.0, 90.0), (12.0, 0.0, 90.0)])
    assert wind.mean(-5.0) == pytest.approx((2.0, 0.0))  # constant before the first key
    assert wind.mean(5.0) == pytest.approx((4.0, math.radians(45.0)))  # halfway: linear
    assert wind.mean(11.0) == pytest.approx((3.0, math.radians(90.0)))
    assert wind.mean(100.0) == pytest.approx((0.0, math.radians(90.0)))  # constant after the last
    # Continuity: the mean wind vector changes at most by its largest rate (3 m/s per s) * dt.
    ts = np.arange(-1.0, 14.0, 0.01)
    vec = np.array([[s * math.cos(d), s * math.sin(d)] for s, d in map(wind.mean, ts)])
    assert np.max(np.linalg.norm(np.diff(vec, axis=0), axis=1)) <= 3.0 * 0.01 * 1.01


def test_params_keys_are_used_and_keys_argument_overrides_them():
    params_keys = [{"time": 0.0, "speed": 1.0, "direction": 0.0}, {"time": 4.0, "speed": 5.0, "direction": 0.0}]
    _, wind = make(keys=params_keys)
    assert wind.mean(2.0)[0] == pytest.approx(3.0)
    _, wind = make(wind_keys=[(0.0, 8.0, 0.0)], keys=params_keys)
    assert wind.mean(2.0)[0] == pytest.approx(8.0)  # a single key: constant
    _, wind = make(wind_keys=params_keys)  # rows may also be dicts, as in params.wind.keys
    assert wind.mean(1.0)[0] == pytest.approx(2.0)


def test_direction_turns_along_the_short_arc():
    _, wind = make(wind_keys=[(0.0, 5.0, 350.0), (10.0, 5.0, 10.0)])
    # Half way from 350 deg to 10 deg through north-east is 0 deg, not 180 deg.
    assert math.cos(wind.mean(5.0)[1]) == pytest.approx(1.0)
    _, wind = make(wind_keys=[(0.0, 5.0, 170.0), (10.0, 5.0, -170.0)])
    assert math.cos(wind.mean(5.0)[1]) == pytest.approx(-1.0)  # through 180, not through 0
    _, wind = make(wind_keys=[(0.0, 5.0, 0.0), (10.0, 5.0, 720.0 + 60.0)])
    assert wind.mean(5.0)[1] == pytest.approx(math.radians(30.0))  # whole turns do not count


@pytest.mark.parametrize("keys, words", [
    ([(0.0, -1.0, 0.0)], ">= 0"),
    ([(1.0, 1.0, 0.0), (1.0, 2.0, 0.0)], "increase"),
    ([(0.0, float("nan"), 0.0)], "finite"),
    ([(0.0, 1.0)], "time_s"),
])
def test_bad_keys_name_the_parameter(keys, words):
    with pytest.raises(ParameterError) as err:
        make(wind_keys=keys)
    assert err.value.key == "wind.keys" and words in str(err.value)


# ------------------------------------------------------------------------- turbulence, eq 13


def test_spatial_correlation_is_that_of_the_121_kernel():
    """Speed 0 and a = cell size: lattice units are the cells, so the measured correlation of
    v' between cells at lag (dx, dy) must be c(dx) c(dy) of the 1-D [1, 2, 1] / 4 filter:
    (1,0): 2/3, (1,1): 4/9, (2,0): 1/6, (3,0): 0."""
    layout, wind = make(blocks=(8, 8), cells_per_block=16, cell_size=0.1, speed=0.0,
                        turbulence=1.0, turbulence_scale=0.1, turbulence_period=1.0)
    assert layout.cells_x == 128  # np.roll wraps 1-3 of 128 columns: a bias far below tol
    # Times 4 periods apart share no key (Catmull-Rom uses 4 keys): independent samples; the
    # fractions 0.37, 0.5... also check that blending keys in time keeps the correlation.
    fields = np.stack([grid(layout, wind.turbulence(4.0 * j + f)) for j, f in
                       enumerate((0.0, 0.37, 0.5, 0.81))])
    var = float(np.mean(fields * fields))
    # Standard error of a sample correlation of a Gaussian field over N values (Bartlett):
    # <= sqrt(2 * sum of rho^2 over all lags / N); N = cells * 2 components * 4 instants.
    n = fields.size
    tol = 4.0 * math.sqrt(2.0 * SUM_RHO2 / n)  # 4 sigma, about 0.03
    for (dx, dy) in ((1, 0), (0, 1), (1, 1), (2, 0), (0, 2), (3, 0), (2, 1)):
        shifted = np.roll(fields, (-dy, -dx), axis=(1, 2))
        measured = float(np.mean(fields * shifted)) / var
        assert measured == pytest.approx(KERNEL_CORR_1D[dx] * KERNEL_CORR_1D[dy], abs=tol), (dx, dy)


@pytest.mark.parametrize("frac", [0.0, 0.25, 0.5])
def test_turbulence_std_is_wind_turbulence_while_drifting_and_blending(frac):
    """std of each component of v' = wind.turbulence (eq 12), also between turbulence keys
    and while the lattice drifts by fractions of a unit across the cells (a = 2.5 cells)."""
    layout, wind = make(blocks=(8, 8), cells_per_block=16, cell_size=0.1, speed=3.3,
                        direction=30.0, turbulence=1.7, turbulence_scale=0.25, turbulence_period=0.5)
    samples = np.stack([wind.turbulence(4 * 0.5 * j + frac * 0.5 + 0.013 * j) for j in range(24)])
    # Instants 4 periods apart are independent. Independent values per instant and component:
    # 52 x 52 units over the sum of squared correlations (3.8 for eq 13; at most ~9 once the
    # bilinear drift smooths further) -> N >= 52^2 * 2 * 24 / 9 ~ 14,000; the relative standard
    # error of a std is 1/sqrt(2 N) <= 0.6 %, so 4 % is over 6 standard errors.
    std = samples.reshape(-1, 2).std(axis=0)
    np.testing.assert_allclose(std, 1.7, rtol=0.04)
    assert abs(samples.mean()) < 0.05 * 1.7


def test_turbulence_is_smooth_in_time_but_independent_after_several_periods():
    layout, wind = make(blocks=(8, 8), cells_per_block=16, cell_size=0.1, speed=0.0,
                        turbulence=1.2, turbulence_scale=0.1, turbulence_period=1.5)
    for t in (0.0, 0.4, 0.77, 1.49, -1.0):
        assert corr(wind.turbulence(t), wind.turbulence(t + 1 / 24)) > 0.95
    # 4 periods later no key is shared: correlation 0 within 4 standard errors.
    n = 128 * 128 * 2
    for t in (0.3, 2.0):
        assert abs(corr(wind.turbulence(t), wind.turbulence(t + 4 * 1.5))) < 4 * math.sqrt(SUM_RHO2 / n)


def test_frozen_turbulence_travels_downwind_with_the_mean_wind():
    """Taylor's hypothesis: after dt = m cells / speed, the pattern seen at cell cx is found at
    cell cx + m (wind towards +X); at the same cell it has changed. These are the wind waves."""
    speed, cs = 2.0, 0.1
    layout, wind = make(blocks=(8, 2), cells_per_block=16, cell_size=cs, speed=speed, direction=0.0,
                        turbulence=1.0, turbulence_scale=cs, turbulence_period=600.0)
    t0, m = 0.25, 3
    dt = m * cs / speed
    before, after = grid(layout, wind.turbulence(t0)), grid(layout, wind.turbulence(t0 + dt))
    # the lattice is unbounded: the columns the pattern moved into are compared
    assert corr(before[:, :-m], after[:, m:]) > 0.999
    assert corr(before, after) < 0.2  # lag 3 of the kernel: no correlation left at the same cell


def test_turbulence_is_continuous_through_time_zero_and_preroll():
    _, wind = make(speed=4.4, turbulence=1.2)
    frames = [wind.sample(f / 24) for f in range(-48, 3)]
    assert all(np.all(np.isfinite(v)) for v in frames)
    assert min(corr(a, b) for a, b in zip(frames, frames[1:])) > 0.8


def test_deterministic_for_any_call_order_and_seed_dependent():
    times = [3.0, 0.5, -1.0, 10.0, 0.5 + 1 / 24, 250.0]
    _, a = make(speed=3.0, seed=7)
    _, b = make(speed=3.0, seed=7)
    first = {t: a.sample(t) for t in times}
    for t in reversed(times):  # other order, and a cache filled by other keys in between
        b.sample(t + 100.0)
        np.testing.assert_array_equal(b.sample(t), first[t])
    _, c = make(speed=3.0, seed=8)
    assert not np.allclose(c.sample(3.0), first[3.0])


def test_zero_turbulence_and_zero_speed():
    layout, wind = make(speed=0.0, turbulence=0.0)
    v = wind.sample(2.0)
    assert v.shape == (layout.n_cells, 2) and v.dtype == np.float32 and v.flags.c_contiguous
    assert not np.any(v)
    layout, wind = make(speed=5.0, direction=0.0, turbulence=0.0)
    np.testing.assert_allclose(wind.sample(1.0), np.broadcast_to([5.0, 0.0], (layout.n_cells, 2)), atol=1e-6)


def test_sample_is_mean_plus_turbulence_for_breezes():
    for kind in ("calm", "gentle_breeze", "moderate_breeze"):
        _, wind = make(type=kind, speed=schema.WIND_TYPE_SPEED[kind], direction=-45.0)
        s, d = wind.mean(1.3)
        expected = wind.turbulence(1.3) + np.array([s * math.cos(d), s * math.sin(d)], dtype=np.float32)
        np.testing.assert_allclose(wind.sample(1.3), expected, atol=1e-5)


# ----------------------------------------------------------------------------------- wind types


def test_type_presets_lie_in_their_beaufort_bands():
    bands = {"calm": (0.0, 0.5), "gentle_breeze": (3.4, 5.4), "moderate_breeze": (5.5, 7.9)}
    for kind, (lo, hi) in bands.items():
        params = schema.from_dict({"wind": {"type": kind}})
        assert lo <= params.wind.speed <= hi
        layout = build_layout(params.replace({"field.blocks_x": 1, "field.blocks_y": 1}))
        assert lo <= WindField(layout, params).mean(0.0)[0] <= hi


def test_blast_gust_front_passes_and_arrives_later_downwind():
    v_mean, g, width, interval = 3.0, 9.0, 6.0, 6.0
    layout, wind = make(blocks=(8, 2), cells_per_block=8, cell_size=0.5, type="blast", speed=v_mean,
                        direction=0.0, turbulence=0.0, gust_speed=g, gust_width=width, gust_interval=interval)
    half = 0.5 * layout.cells_x * 0.5  # 16 m: the field spans x in [-16, 16]
    ts = np.arange(0.0, 8.0, 1 / 48)
    peaks = []
    for x in (-8.0, 8.0):
        c = cell_at(layout, x, 0.0)
        x = float(layout.cell_center[c, 0])
        speed = np.array([np.linalg.norm(wind.sample(t)[c]) for t in ts])
        # The front of t = 0 starts 3 widths upwind of the edge, moves at v + g / 2.
        t_pass = (x + half + 3 * width) / (v_mean + g / 2)
        i = int(np.argmin(np.abs(ts - t_pass)))
        i = i - 48 + int(np.argmax(speed[i - 48:i + 48]))  # the peak of this front
        assert speed[i] == pytest.approx(v_mean + g, rel=0.02)  # the gust adds g at its centre
        assert ts[i] == pytest.approx(t_pass, abs=1 / 24)
        # Rises before, falls after (the Gaussian front is 2 * width / (v + g/2) = 1.6 s wide),
        # and 2 s (2.5 widths) before and after it the wind is back to the mean (no other
        # front is near then: the previous one left, the next starts at t = 6 s, 34 m upwind).
        assert np.all(np.diff(speed[i - 48:i + 1]) >= -1e-4)
        assert np.all(np.diff(speed[i:i + 48]) <= 1e-4)
        for t_far in (t_pass - 2.0, t_pass + 2.0):
            assert speed[int(np.argmin(np.abs(ts - t_far)))] < v_mean + 0.05 * g
        peaks.append(ts[i])
    assert peaks[1] - peaks[0] == pytest.approx(16.0 / (v_mean + g / 2), abs=1 / 24)
    # The gust blows along the mean wind: no cross-wind component without turbulence.
    assert np.max(np.abs(wind.sample(2.0)[:, 1])) < 1e-5


def test_whirlwind_is_a_counter_clockwise_rankine_vortex():
    radius, peak = 3.0, 9.0
    layout, wind = make(blocks=(8, 8), cells_per_block=8, cell_size=0.25, type="whirlwind", speed=0.0,
                        turbulence=0.0, vortex_radius=radius, vortex_speed=peak)
    np.testing.assert_allclose(wind.vortex_center(5.0), [0.0, 0.0])  # no mean wind: it stays
    v = wind.sample(5.0)
    p = layout.cell_center.astype(np.float64)
    r = np.hypot(p[:, 0], p[:, 1])
    tangential = (p[:, 0] * v[:, 1] - p[:, 1] * v[:, 0]) / r  # (r x v)_z / r
    radial = (p[:, 0] * v[:, 0] + p[:, 1] * v[:, 1]) / r
    inner = r < 4.0  # a quarter of the 16 m field: no fading towards the periodic images
    assert np.all(tangential[inner] > 0)  # counter-clockwise seen from +Z
    assert np.all(radial[inner] < 0)  # mild inflow
    core = r < radius
    # Rankine: solid rotation in the core (v = V r / R), free vortex outside (v r = V R,
    # i.e. the circulation 2 pi r v is the same on every circle outside the core).
    np.testing.assert_allclose(tangential[core], peak * r[core] / radius, rtol=1e-4)
    outer = inner & (r > radius)
    np.testing.assert_allclose(tangential[outer] * r[outer], peak * radius, rtol=1e-4)
    speed = np.linalg.norm(v, axis=1)
    assert abs(r[np.argmax(np.where(inner, speed, 0))] - radius) < 0.25  # fastest at r = R


def test_whirlwind_travels_with_the_mean_wind_and_comes_back():
    layout, wind = make(blocks=(4, 4), cells_per_block=8, cell_size=0.5, type="whirlwind", speed=2.0,
                        direction=0.0, turbulence=0.0, vortex_radius=1.0, vortex_speed=6.0)
    size = layout.cells_x * 0.5  # 16 m
    for t, x in ((0.0, 0.0), (2.0, 4.0), (4.0, -8.0), (6.0, -4.0), (8.0, 0.0)):
        centre = wind.vortex_center(t)
        assert centre == pytest.approx([x, 0.0], abs=1e-9)  # wrapped into [-8, 8)
        # The eye: where the vorticity dv_y/dx - dv_x/dy (2 V / R in a Rankine core) peaks.
        v = grid(layout, wind.sample(t))
        curl = (np.roll(v[..., 1], -1, axis=1) - np.roll(v[..., 1], 1, axis=1)
                - np.roll(v[..., 0], -1, axis=0) + np.roll(v[..., 0], 1, axis=0)) / (2 * 0.5)
        eye = layout.cell_center[int(np.argmax(curl))]
        dx = (eye[0] - centre[0] + size / 2) % size - size / 2
        assert abs(dx) <= 0.5 and abs(eye[1] - centre[1]) <= 0.5, (t, eye, centre)


EXTREMES = [
    {},
    {"speed": 0.0, "turbulence": 0.0, "gust_speed": 0.0, "vortex_speed": 0.0},
    {"speed": 60.0, "turbulence": 30.0, "turbulence_scale": 0.01, "turbulence_period": 0.05,
     "gust_speed": 60.0, "gust_width": 0.1, "gust_interval": 0.5, "vortex_radius": 0.1, "vortex_speed": 60.0},
    {"speed": 0.0, "turbulence": 30.0, "turbulence_scale": 100.0, "turbulence_period": 600.0,
     "gust_speed": 1e-3, "gust_width": 1000.0, "gust_interval": 3600.0, "vortex_radius": 1000.0},
]


@pytest.mark.parametrize("kind", schema.WIND_TYPES)
@pytest.mark.parametrize("extreme", range(len(EXTREMES)))
def test_no_nan_for_extreme_values(kind, extreme):
    for blocks, cpb, cs in (((1, 1), 1, 0.01), ((2, 1), 4, 10.0)):
        layout, wind = make(blocks=blocks, cells_per_block=cpb, cell_size=cs, type=kind, **EXTREMES[extreme])
        for t in (-600.0, -2.0, 0.0, 1e-3, 1e6):
            v = wind.sample(t)
            assert v.shape == (layout.n_cells, 2) and v.dtype == np.float32
            assert np.all(np.isfinite(v)), (kind, extreme, blocks, t)
            assert np.all(np.isfinite(wind.mean(t)))


def test_huge_field_with_tiny_units_stays_finite():
    """Units finer than half a cell are coarsened to half a cell; v' keeps the requested std."""
    layout, wind = make(blocks=(16, 16), cells_per_block=8, cell_size=10.0, turbulence=2.0,
                        turbulence_scale=0.01)
    v = wind.turbulence(1.0)
    assert np.all(np.isfinite(v))
    assert v.std() == pytest.approx(2.0, rel=0.1)


def test_advection_integral_of_turning_keys():
    """D(t) = integral of the mean wind: v = 2 (cos t, sin t) m/s turning 1 rad/s for pi s
    carries the air along a half circle of radius 2 m, from (0, 0) to (0, 4)."""
    _, wind = make(wind_keys=[(0.0, 2.0, 0.0), (math.pi, 2.0, 179.999)])
    np.testing.assert_allclose(wind.displacement(math.pi), [0.0, 4.0], atol=1e-3)
    np.testing.assert_allclose(wind.displacement(math.pi / 2), [2.0, 2.0], atol=1e-3)
    # Before the first key and after the last the wind is constant: D is linear there.
    np.testing.assert_allclose(wind.displacement(-1.0), [-2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(wind.displacement(math.pi + 1.0) - wind.displacement(math.pi),
                               [-2.0, 2.0 * math.sin(math.radians(179.999))], atol=1e-6)


def test_gust_waves_travel_downwind_at_the_mean_wind_and_scale_it():
    """Gust waves (gusts.py): the wind's speed pattern at t + dt is the one at t carried dt * v-bar
    downwind (frozen, like the turbulence); it scales the mean wind by 1 +- gust_waves; none when
    gust_waves is 0 (the same bits as before)."""
    from windgrass.grass_addon.layout import build_layout

    params = schema.defaults().replace({"field.blocks_x": 2, "field.blocks_y": 2, "wind.turbulence": 0.0,
                                        "wind.speed": 6.0, "wind.direction": 30.0, "wind.gust_waves": 0.5,
                                        "wind.gust_wave_size": 12.0})
    layout = build_layout(params)
    wind = WindField(layout, params)
    rng = np.random.default_rng(3)
    xy = rng.uniform(-200.0, 200.0, (500, 2))
    t, dt = 4.0, 1.5
    carried = xy + dt * 6.0 * np.array([math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    now, later = wind.sample(t, xy), wind.sample(t + dt, carried)
    assert np.allclose(np.hypot(*now.T), np.hypot(*later.T), atol=1e-4)
    speed = np.hypot(*now.T)
    assert speed.min() >= 6.0 * 0.5 - 1e-4 and speed.max() <= 6.0 * 1.5 + 1e-4
    assert speed.std() > 0.5  # patches of stronger and weaker wind
    assert np.allclose(np.degrees(np.arctan2(now[:, 1], now[:, 0])), 30.0, atol=1e-3)  # along the mean wind
    tile = gusts.pattern(7)
    assert tile.shape == (64, 64) and abs(float(tile.mean()) - 0.5) < 0.05
    # it tiles: the value just inside one edge continues from the opposite edge
    m = gusts.tile_metres(params)
    inside, beyond = np.array([[0.001, 5.0]]), np.array([[m + 0.001, 5.0]])
    assert np.allclose(gusts.sample(tile, inside, m), gusts.sample(tile, beyond, m))
    # the fast sample is its plain twin's (the four pixels around a point, weighted), bit for bit,
    # its offset the same as subtracting it, at points on both sides of the tile's edges
    far = rng.uniform(-3.0 * m, 3.0 * m, (2000, 2))
    offset = np.array([0.37 * m, -1.9 * m])
    assert np.array_equal(gusts.sample(tile, far, m, offset), gusts.sample_twin(tile, far - offset, m))
    odd = tile[:60, :60]  # (a tile whose side is no power of two wraps by the remainder)
    assert np.array_equal(gusts.sample(odd, far, m), gusts.sample_twin(odd, far, m))
    plain = WindField(layout, params.replace({"wind.gust_waves": 0.0}))
    assert np.allclose(np.hypot(*plain.sample(t, xy).T), 6.0)


def _half_reach(corr: np.ndarray, dx: float, dy: float) -> float:
    """Pixels along (dx, dy) until the (periodic) autocorrelation ``corr`` falls to a half."""
    n = corr.shape[0]
    for r in np.arange(0.25, n / 2, 0.25):
        x, y = r * dx, r * dy
        i, j = int(np.floor(y)) % n, int(np.floor(x)) % n
        fy, fx = y - np.floor(y), x - np.floor(x)
        c = (corr[i, j] * (1 - fx) * (1 - fy) + corr[i, (j + 1) % n] * fx * (1 - fy)
             + corr[(i + 1) % n, j] * (1 - fx) * fy + corr[(i + 1) % n, (j + 1) % n] * fx * fy)
        if c < 0.5:
            return float(r)
    return n / 2


def test_a_gust_wave_is_a_band_across_the_wind():
    """Seen from above a gust runs over a meadow as a band across the wind: the pattern's patches
    are about ``wind.gust_stretch`` times longer across the wind than along it, whichever way it blows
    (the pattern's autocorrelation falls to a half that many times further across than along)."""
    for direction in (0.0, 60.0, 135.0):
        tile = gusts.pattern(7, direction, 2.5).astype(np.float64) - 0.5
        corr = np.real(np.fft.ifft2(np.abs(np.fft.fft2(tile)) ** 2))
        corr /= corr[0, 0]
        a = np.radians(direction)
        along, across = _half_reach(corr, math.cos(a), math.sin(a)), _half_reach(corr, -math.sin(a), math.cos(a))
        assert 0.6 * 2.5 < across / along < 1.6 * 2.5, (direction, along, across)
