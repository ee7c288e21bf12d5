"""Random parameter sets inside the schema's hard ranges: the engine stays physical for all of them.

Small and seeded (a few seconds): every wind type and several frame rates, blades of every length,
stiffness, density and damping the schema accepts. For each set the state stays finite, no blade
vertex or card corner goes below the (flat) ground, and no tip is farther from its root than the
blade is long.
"""

import math

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.field import GrassField

RUNS = 120
DRAWN = ("blade.segments", "blade.tip_width", "blade.inclination", "blade.root_stiffness",
         "blade.stiffness_offset", "blade.density", "blade.nonlinear_stiffness", "blade.response_torque",
         "blade.twist_stiffness", "blade.damping_mass", "blade.damping_stiffness", "blade.boundary_k",
         "blade.boundary_lambda", "wind.speed", "wind.turbulence", "wind.turbulence_scale",
         "wind.turbulence_period", "wind.gust_speed", "wind.vortex_speed", "wind.vortex_radius")
SPECIES = {f.key: f for f in schema.SPECIES_FIELDS}


def _draw(p: schema.Param, rng: np.random.Generator):
    """A value in p's hard range: log-uniform over wide positive ranges, else uniform."""
    lo, hi = p.minimum, p.maximum
    if p.kind == "int":
        return int(rng.integers(lo, hi + 1))
    if lo > 0 and hi / lo > 100:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    return float(rng.uniform(lo, hi))


def random_params(index: int) -> schema.Params:
    rng = np.random.default_rng([2026, index])
    values = {name: _draw(schema.BY_NAME[name], rng) for name in DRAWN}
    values.update({
        "field.blocks_x": 2, "field.blocks_y": 1, "field.cells_per_block": int(rng.integers(1, 5)),
        "field.blades_per_cell": int(rng.integers(1, 4)),
        "field.cell_size": _draw(schema.BY_NAME["field.cell_size"], rng),
        "field.seed": int(rng.integers(0, 1000)),
        "wind.type": schema.WIND_TYPES[index % len(schema.WIND_TYPES)],
        "render.fps": (12, 24, 30, 60)[index % 4], "simulation.preroll": 0.5,
    })
    species = {key: _draw(SPECIES[key], rng) for key in ("length", "length_variation", "width", "stiffness")}
    params = schema.defaults().replace(values)
    if values["wind.type"] in schema.WIND_TYPE_PRESETS:  # keep the drawn speeds over the preset's
        params = params.replace({k: values[k] for k in ("wind.speed", "wind.turbulence")})
    return params.replace({"blade.species": [{"name": "drawn", **species}]})


@pytest.mark.parametrize("index", range(RUNS))
def test_random_parameters_stay_physical(index):
    params = random_params(index)
    field = GrassField(params)
    layout = field.layout
    n = layout.segments
    blocks = field.all_blocks()
    for frame in (1, 6, 13):
        cells = field.seek(frame)
        state = field.sim.state
        for name in ("bend_t", "bend_vel_t", "twist_t", "twist_vel_t"):
            assert np.isfinite(getattr(state, name)).all(), (name, frame)
        v = field.blade_vertices(blocks).reshape(layout.n_blades, n + 1, 2, 3)
        assert np.isfinite(v).all()
        assert v[..., 2].min() >= -1e-6, f"a blade below the ground at frame {frame}"
        reach = np.linalg.norm(v[:, -1].mean(axis=1) - v[:, 0].mean(axis=1), axis=1)
        # within the float32 resolution of positions this far from the origin (fields of 10 m cells)
        resolution = 8 * np.finfo(np.float32).eps * float(np.abs(v).max())
        assert np.all(reach <= layout.blade_length * (1 + 1e-4) + resolution + 1e-6)
        cards = field.card_vertices(blocks)
        assert np.isfinite(cells.card_offset).all() and cards[:, 2].min() >= -1e-6
