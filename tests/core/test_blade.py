"""Rest shape of a blade (paper III.A, eqs 1-6): stiffness along the blade and gravity droop."""

import numpy as np
import pytest
from windgrass.grass_addon import blade

N = 5
OFFSET = 0.05  # x of eq 1 (schema default)
DENSITY = 0.003  # rho_grass, kg/m (schema default)
MU_ROOT = 8.0e-4  # mu_root of eq 1 (schema default)
INCLINATION = float(np.radians(10.0))  # alpha, the random initial inclination of III.A


def rest(length, mu_root=MU_ROOT, inclination=INCLINATION, density=DENSITY):
    """Absolute rest tilt of each segment of one blade, and its joint angles."""
    seg = np.array([length / N])
    mu = blade.joint_stiffness(np.array([mu_root]), seg, N, OFFSET)
    theta = blade.rest_angles(np.array([inclination]), seg, mu, density, iterations=200)
    return blade.rest_tilt(np.array([inclination]), theta)[0], theta[0], mu[0]


def test_root_is_stiffer_than_tip_eq1():
    mu = blade.joint_stiffness(np.array([MU_ROOT]), np.array([0.064]), N, OFFSET)[0]
    # eq 1: mu(L) = mu_root / (L + x), falling with the distance from the root
    assert np.all(np.diff(mu) < 0)
    assert mu[0] == pytest.approx(MU_ROOT / OFFSET, rel=1e-5)
    assert mu[3] == pytest.approx(MU_ROOT / (3 * 0.064 + OFFSET), rel=1e-5)


def test_zero_inclination_stays_upright():
    # Fig. 5: an upright blade has no lever for its weight, so gravity cannot bend it
    tilt, theta, _ = rest(0.32, inclination=0.0)
    assert np.allclose(theta, 0.0) and np.allclose(tilt, 0.0)


def test_longer_blades_droop_more():
    tips = [rest(length)[0][-1] for length in (0.15, 0.32, 0.6)]
    assert tips[0] < tips[1] < tips[2]


def test_softer_blades_droop_more():
    tips = [rest(0.32, mu_root=mu)[0][-1] for mu in (3.2e-3, 8.0e-4, 3.0e-4)]
    assert tips[0] < tips[1] < tips[2]


def test_droop_grows_towards_the_tip():
    # each joint only adds bend in the direction of the lean: the tilt increases root -> tip
    tilt, theta, _ = rest(0.32)
    assert np.all(theta >= 0) and np.all(np.diff(tilt) > 0)


def test_default_blade_has_a_natural_droop():
    # the schema defaults are chosen for a natural look: a 0.32 m blade's tip near 25 degrees
    tilt, _, _ = rest(0.32, inclination=np.radians(9.0))  # the mean of the random alpha in [0, 18]
    assert 12.0 < np.degrees(tilt[-1]) < 40.0


def test_converged_statics_is_a_torque_balance():
    # eqs 3-4 and 6: at rest mu_i theta_i equals the torque of the weight above joint i, with
    # the exact lever (horizontal distance from joint i to each segment's centre)
    length = 0.4
    tilt, theta, mu = rest(length)
    seg = length / N
    weight = DENSITY * seg * blade.GRAVITY  # eq 2
    dx = seg * np.sin(tilt)
    joint_x = np.concatenate([[0.0], np.cumsum(dx)[:-1]])
    centre_x = joint_x + 0.5 * dx
    torque = np.array([weight * np.sum(centre_x[i:] - joint_x[i]) for i in range(N)])
    assert np.allclose(mu * theta, torque, rtol=2e-3, atol=1e-9)


def _tip_positions(segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Rest tip (horizontal, vertical) of every blade of a field drawn with `segments` segments,
    in blade lengths, and the tip segment's tilt in degrees (the same blades for any count)."""
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.layout import build_layout

    layout = build_layout(schema.defaults().replace({"field.blocks_x": 2, "field.blocks_y": 2,
                                                     "blade.segments": segments}))
    tilt = layout.blade_rest_tilt.astype(np.float64)
    tip = np.stack([np.sin(tilt).mean(axis=1), np.cos(tilt).mean(axis=1)], axis=1)
    return tip, np.degrees(tilt[:, -1])


def test_rest_shape_converges_as_segments_are_added():
    """A blade's shape is a property of the blade, not of its drawing: compared with 12 segments,
    the tips of 6-segment blades lie within 1 % of the blade length (median; 99 % within 5 %), the
    median tip tilt within 1 degree, and 8 segments come closer than 5."""
    fine, fine_tilt = _tip_positions(12)
    error = {}
    for n in (5, 6, 8):
        tip, tilt = _tip_positions(n)
        error[n] = np.linalg.norm(tip - fine, axis=1)
        if n == 6:
            assert np.median(error[n]) < 0.01 and np.percentile(error[n], 99) < 0.05
            assert abs(np.median(tilt) - np.median(fine_tilt)) < 1.0
    assert np.median(error[8]) < np.median(error[6]) < np.median(error[5])


def test_a_blade_too_soft_for_its_weight_lies_on_the_ground():
    """Soft, heavy, steeply inclined blades (values inside the UI's ranges) droop onto the ground
    and stop there: no segment tilts past the ground, none curls back up or into a coil."""
    inclination = np.radians(np.linspace(0.0, 80.0, 9))
    seg = np.full(9, 0.4 / N)
    mu = blade.joint_stiffness(np.full(9, 1e-4), seg, N, OFFSET)
    theta = blade.rest_angles(inclination, seg, mu, 0.05)
    tilt = blade.rest_tilt(inclination, theta)
    assert np.all(np.isfinite(tilt))
    assert tilt.max() <= blade.GROUND_TILT + 1e-6
    assert np.all(theta >= -1e-7)
    assert np.degrees(tilt[1:, -1]).min() > 80.0  # the heavy blades do lie down


def test_blocks_rest_shapes_worked_out_together_are_each_blocks_own():
    """``rest_angles_blocks`` (a cache makes its blocks' rest shapes in one pass) gives each block
    the bits ``rest_angles`` gives it alone, though the blocks stop iterating at different times
    (a stiff block settles in a few iterations, a soft one runs them all) and only some have
    blades that the ground stops."""
    rng = np.random.default_rng(11)
    B = 300
    kinds = {"stiff": (0.02, 0.1, 0.2), "meadow": (MU_ROOT, 0.3, 0.3), "lying": (2e-5, 0.6, 0.5)}
    inclination, seg, mu, alone = [], [], [], []
    for mu_root, length, tilt in kinds.values():
        inc = rng.uniform(0.0, tilt, B)
        s = np.full(B, length / N) * rng.uniform(0.7, 1.3, B)
        m = blade.joint_stiffness(mu_root * rng.uniform(0.5, 1.5, B), s, N, OFFSET)
        inclination.append(inc)
        seg.append(s)
        mu.append(m)
        alone.append(blade.rest_angles(inc, s, m, DENSITY))
    together = blade.rest_angles_blocks(np.stack(inclination), np.stack(seg), np.stack(mu), DENSITY)
    for k, name in enumerate(kinds):
        assert np.array_equal(together[k], alone[k]), name
    # (the cases are what they say: the stiff block settled early, the soft one lies on the ground)
    assert np.array_equal(blade.rest_angles(inclination[0], seg[0], mu[0], DENSITY, iterations=10), alone[0])
    lying = blade.rest_tilt(inclination[2], alone[2])
    assert np.isclose(lying.max(), blade.GROUND_TILT, atol=1e-6)
    assert blade.rest_tilt(inclination[1], alone[1]).max() < blade.GROUND_TILT - 0.1
