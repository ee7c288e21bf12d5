"""Far grass computed from the field's own blades (sward.py): the card atlas covers what the
cell's blades cover, in the blade material's colours; the far canopy's height and colour are the
sward's."""

import numpy as np
import pytest
from windgrass.grass_addon import atlas, presets, schema, sward


@pytest.fixture(params=["default", "meadow"])
def params(request):
    p = schema.defaults().replace({"field.blades_per_cell": 3})
    return p if request.param == "default" else presets.apply_preset(p, "meadow")


def test_cards_cover_what_their_blades_cover(params):
    """A card stands for its cell's blades: the atlas's mean opacity is the blades' projected
    area (width across the card times height, tapering) over the card's area."""
    mean_alpha, blade_share = atlas.card_coverage(params)
    assert 0.01 < blade_share < 0.5
    assert mean_alpha == pytest.approx(blade_share, rel=0.25)


def test_card_atlas_is_the_blades_colours_rooted_at_the_bottom(params):
    image = atlas.card_atlas(params)
    size = atlas.CARD_PIXELS
    assert image.shape == (size, atlas.CARD_VARIANTS * size, 4) and image.dtype == np.float32
    alpha = image[..., 3]
    rows = alpha.mean(axis=1)
    assert rows[: size // 8].mean() > rows[size // 2: 5 * size // 8].mean()  # blades taper, tips droop
    # opaque pixels take the blade material's ramp: from the dark base to a shaded species colour
    colours = sward.Species(params).color
    rgb = image[..., :3][alpha > 0.5]
    assert rgb.size and np.all(rgb <= 1.3 * colours.max(axis=0) + 1e-6)
    assert np.all(rgb >= 0.7 * np.asarray(sward.BLADE_BASE_COLOUR) - 1e-6)
    assert (rgb[:, 1] >= rgb[:, 2]).mean() > 0.95  # green over blue, like every species colour
    # each variant shows different blades
    variants = alpha.reshape(size, atlas.CARD_VARIANTS, size).transpose(1, 0, 2)
    assert not np.array_equal(variants[0], variants[1])


def test_far_canopy_is_the_swards_height_and_colour(params):
    tips = sward.tip_heights(params)
    height = sward.canopy_height(params)
    assert 0.5 * tips.mean() < height < tips.mean() < max(r["length"] for r in params.species()) * 1.5
    colour = np.array(sward.sward_colour(params))
    species = sward.Species(params)
    tip = species.p @ species.color
    # the visible upper part of the blades: darker than the tips, lighter than the roots
    assert np.all(colour <= tip + 1e-6) and np.all(colour >= np.asarray(sward.BLADE_BASE_COLOUR))
    assert np.all(colour >= 0.6 * tip)


def _ray_blocked(params, exit_z: float, slope: float, rays: int, rng) -> float:
    """Share of rays stopped by blades, traced through a periodic field of copies of the sample
    block: each ray leaves the field at height ``exit_z`` and, traced back towards the camera,
    rises by ``slope`` per metre until it clears the tallest tip. Blades are the kinematics'
    strips at rest: segment j leans by rest_tilt[j] towards the blade's facing, its side vector
    is horizontal and square to the facing, its width tapers linearly."""
    block = sward.sample_blades(params)
    n = int(params.blade.segments)
    facing = block.blade_facing.astype(np.float64)
    tilt = block.blade_rest_tilt.astype(np.float64)
    step = block.blade_length.astype(np.float64)[:, None] / n
    seg = np.stack([step * np.sin(tilt) * np.cos(facing)[:, None], step * np.sin(tilt) * np.sin(facing)[:, None],
                    step * np.cos(tilt)], axis=-1)  # (blades, n, 3)
    joints = block.blade_root.astype(np.float64)[:, None, :] + np.concatenate(
        [np.zeros_like(seg[:, :1]), np.cumsum(seg, axis=1)], axis=1)
    taper = 1.0 - (1.0 - params.blade.tip_width) * np.arange(n + 1) / n
    width = block.blade_width.astype(np.float64)[:, None] * taper
    side = np.stack([-np.sin(facing), np.cos(facing), np.zeros_like(facing)], axis=1)
    reach = (joints[..., 2].max() - exit_z) / slope  # horizontal length of the traced part of a ray
    tile = float(params.field.cells_per_block * params.field.cell_size)
    k = np.arange(-int(np.ceil(reach / tile)) - 1, int(np.ceil(reach / tile)) + 2)
    shifts = np.stack(np.meshgrid(k * tile, k * tile, [0.0], indexing="ij"), axis=-1).reshape(-1, 1, 1, 3)
    copies = len(shifts)
    p0 = (joints[None, :, :-1] + shifts).reshape(-1, 3)  # every segment of every copy
    u = np.broadcast_to(seg, (copies, *seg.shape)).reshape(-1, 3)
    s = np.broadcast_to(side[:, None], (copies, len(facing), n, 3)).reshape(-1, 3)
    w0 = np.broadcast_to(width[:, :-1], (copies, len(facing), n)).reshape(-1)
    w1 = np.broadcast_to(width[:, 1:], (copies, len(facing), n)).reshape(-1)
    lo = block.blade_root[:, :2].min(axis=0).astype(np.float64)
    batch, blocked = 50, 0
    for _ in range(rays // batch):
        psi = rng.uniform(0.0, 2.0 * np.pi, batch)
        exit_point = np.column_stack([lo + rng.uniform(0.0, tile, (batch, 2)), np.full(batch, exit_z)])
        back = np.column_stack([-np.cos(psi), -np.sin(psi), np.full(batch, slope)])[:, None]  # to the camera
        # exit + t back = p0 + a u + c s, solved for (a, c, t) by Cramer's rule
        rhs = exit_point[:, None, :] - p0[None]
        uu = np.broadcast_to(u, rhs.shape)
        s_x_back = np.cross(s, -back)
        det = np.einsum("rqi,rqi->rq", uu, s_x_back)
        det = np.where(np.abs(det) < 1e-12, np.inf, det)
        a = np.einsum("rqi,rqi->rq", rhs, s_x_back) / det
        c = np.einsum("rqi,rqi->rq", uu, np.cross(rhs, -back)) / det
        t = np.einsum("rqi,rqi->rq", uu, np.cross(s, rhs)) / det
        half = 0.5 * (w0 + (w1 - w0) * a)
        hit = (a >= 0) & (a <= 1) & (np.abs(c) <= half) & (t >= 0) & (t <= reach)
        blocked += int(hit.any(axis=1).sum())
    return blocked / (rays // batch * batch)


@pytest.mark.slow
@pytest.mark.parametrize("slope", [0.1, 0.2])
def test_sward_depth_is_what_rays_leaving_the_field_cross(params, slope):
    """The canopy's edge lets through what the blades would: a ray leaving the field at height z
    with slope s is stopped with probability 1 - exp(-tau(z) / s), checked against rays traced
    through the blade strips themselves. The sward leans (segments 25-50 degrees from the
    vertical), so a leaning segment must count with its rise, not its whole face (1.5-2 times
    more)."""
    params = params.replace({"field.cells_per_block": 4, "blade.inclination": 35.0, "blade.root_stiffness": 5e-4})
    heights, depth = sward.sward_profile(params)
    assert depth[0] > 0.0 and depth[-1] == pytest.approx(0.0, abs=1e-9) and np.all(np.diff(depth) <= 1e-12)
    rng = np.random.default_rng(7)
    for target in (0.5, 0.25):  # heights where the sward stops about half and a quarter of such rays
        z = float(np.interp(-slope * np.log(1.0 - target), depth[::-1], heights[::-1]))
        expected = 1.0 - np.exp(-float(np.interp(z, heights, depth)) / slope)
        assert expected == pytest.approx(target, abs=0.02)
        assert _ray_blocked(params, z, slope, 800, rng) == pytest.approx(expected, abs=0.07)
