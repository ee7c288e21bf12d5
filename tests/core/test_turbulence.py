"""A Turbulence force field as Blender computes it (its effect on Blender's particles is the oracle
in tests/blender/test_interaction.py): Perlin's improved noise, three octaves, each component read
at the point's coordinates turned, at its offset from the field plus the field's Z axis."""

from __future__ import annotations

import math

import numpy as np
from windgrass.grass_addon import forces


def _reference_perlin(x: float, y: float, z: float) -> float:
    """Perlin's improved noise (2002) a point at a time, as written in his reference, over the
    same permutation."""
    p = [int(v) for v in forces._PERMUTATION]
    X, Y, Z = math.floor(x) & 255, math.floor(y) & 255, math.floor(z) & 255
    x, y, z = x - math.floor(x), y - math.floor(y), z - math.floor(z)

    def fade(t):
        return t * t * t * (t * (t * 6 - 15) + 10)

    def lerp(t, a, b):
        return a + t * (b - a)

    def grad(h, x, y, z):
        h &= 15
        u = x if h < 8 else y
        v = y if h < 4 else (x if h in (12, 14) else z)
        return (u if h & 1 == 0 else -u) + (v if h & 2 == 0 else -v)

    u, v, w = fade(x), fade(y), fade(z)
    A = p[X] + Y
    AA, AB = p[A] + Z, p[A + 1] + Z
    B = p[X + 1] + Y
    BA, BB = p[B] + Z, p[B + 1] + Z
    return lerp(w, lerp(v, lerp(u, grad(p[AA], x, y, z), grad(p[BA], x - 1, y, z)),
                        lerp(u, grad(p[AB], x, y - 1, z), grad(p[BB], x - 1, y - 1, z))),
                lerp(v, lerp(u, grad(p[AA + 1], x, y, z - 1), grad(p[BA + 1], x - 1, y, z - 1)),
                     lerp(u, grad(p[AB + 1], x, y - 1, z - 1), grad(p[BB + 1], x - 1, y - 1, z - 1))))


def test_the_fast_noise_is_perlins_reference_noise():
    points = np.random.default_rng(4).uniform(-300.0, 300.0, (500, 3))
    fast = forces.perlin(points)
    assert np.allclose(fast, [_reference_perlin(*p) for p in points], atol=1e-12)


def test_the_noise_is_zero_on_its_lattice_bounded_and_continuous():
    lattice = np.random.default_rng(5).integers(-500, 500, (200, 3)).astype(np.float64)
    assert np.all(forces.perlin(lattice) == 0.0)
    points = np.random.default_rng(6).uniform(-50.0, 50.0, (20000, 3))
    values = forces.perlin(points)
    assert np.abs(values).max() <= 1.0 and values.std() > 0.1
    step = forces.perlin(points + 1e-4) - values  # a gradient of at most a few units
    assert np.abs(step).max() < 1e-3


def test_an_as_added_turbulence_reads_its_noise_over_one_metre_eddies_above_its_centre():
    """Add > Force Field > Turbulence gives a size of 0: Blender reads it as 1 m. The noise is read
    at the offset from the field plus its Z axis (a field turned on its side reads it sideways)."""
    upright = forces.Effector(kind="turbulence", matrix=forces.euler_matrix((1.0, 2.0, 0.0), (0.0, 0.0, 0.0)),
                              strength=1.0, size=0.0)
    points = np.array([[1.0, 2.0, 0.0], [3.0, 2.5, 0.2]])
    assert np.allclose(forces.turbulence_offsets(upright, points), [[0.0, 0.0, 1.0], [2.0, 0.5, 1.2]])
    assert np.allclose(forces.turbulence_offsets(upright, points),
                       forces.turbulence_offsets(forces.Effector(**{**upright.__dict__, "size": 1.0}), points))
    halved = forces.Effector(**{**upright.__dict__, "size": 2.0})
    assert np.allclose(forces.turbulence_offsets(halved, points), [[0.0, 0.0, 0.5], [1.0, 0.25, 0.6]])
    sideways = forces.Effector(**{**upright.__dict__, "matrix": forces.euler_matrix((1.0, 2.0, 0.0), (0.0, 90.0, 0.0))})
    assert np.allclose(forces.turbulence_offsets(sideways, points[:1]), [[1.0, 0.0, 0.0]], atol=1e-12)


def test_each_component_reads_the_noise_at_the_coordinates_turned():
    """Blender's three components: the turbulence at (x, y, z), (y, z, x) and (z, x, y) (so that
    they differ), each octave twice the frequency and half the amplitude of the one before."""
    q = np.random.default_rng(7).uniform(-20.0, 20.0, (300, 3))
    vector = forces.turbulence_vector(q)

    def octaves(p):
        return sum(0.5 ** k * forces.perlin(p * 2.0 ** k) for k in range(3)) / 1.75

    assert np.allclose(vector[:, 0], octaves(q))
    assert np.allclose(vector[:, 1], octaves(q[:, [1, 2, 0]]))
    assert np.allclose(vector[:, 2], octaves(q[:, [2, 0, 1]]))
    assert np.corrcoef(vector[:, 0], vector[:, 1])[0, 1] < 0.3  # three fields, not one
