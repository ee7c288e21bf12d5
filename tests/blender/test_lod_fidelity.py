"""Levels of detail against all geometry (paper VI: "little perceivable loss in image quality").

Cycles renders of a fixed camera over a calm 25.6 m field at tiny resolution, in sun and under an
overcast sky, for the paper's even field (``even``), the meadow species and a painted field (a path to the far edge
and a density gradient, with the LOD bands brought close so the path crosses blades, cards and the
far canopy): the LOD render against the same frame with every blade as geometry
(``headless/lod_compare.py``, which prints the same figures at full size). And the strip view: a
narrow camera 1.1 m and 6 m up looking along a field 102 m long, so each band is seen from grazing
to steep slopes (the far canopy from 0.01 to 0.18), where a flat far texture came out up to twice
as bright as the grass and the cards 15 % dark.

Each comparison is two renders by one Blender of the engine's LOD, which is the same on every line:
``dev.py test`` runs this module on Blender 5.2 LTS only (a quarter of the Blender tests' time on
4.5 LTS; ``dev.py test tests/blender/test_lod_fidelity.py`` runs it on both).
"""

import json

import lod_compare
import pytest

# The default scene's meadow with its look (tussocks, patches of species, flowers and seed heads:
# issue #34) is not compared here (four more renders): `dev.py lod --presets default` prints its
# figures (the square view at 320x180 within 0.019 overcast, 0.033 in sun: docs/performance.md).
# Goals: every image row's mean colour within 0.04 (linear RGB), including the rows where the
# field's far edge (22 m away, blade tips up to 0.5 m tall) meets the sky; the image within 0.03.
ROW_GOAL = 0.04
IMAGE_GOAL = 0.03
# No tone step between the bands: each grass row's mean green within 15 % of the all-geometry
# row's (the even field's species; at 96x54 and 6 samples a row's noise is a few per cent).
SEAM_GOAL = 0.15
# The Meadow preset's six species (issue #34: fine and broad grasses, timothy, buttercups, daisies,
# dry grass) in the default scene's patches: under an overcast sky the square view's row where the
# field's far edge meets the sky was 0.067 off (the far canopy's edge as tall as the field's mean
# where the stands at the edge are short); reading the height of the stand each ray crossed last
# (sward.patch_stands) brought it to 0.039 on Blender 5.2, and the sward's profile taken over the
# field's blocks, not block 0 alone (sward.sample_blades: right for the default meadow's seed
# heads, 0.075 -> 0.013) and scaled by the stand's height (L tau(z/L)), to 0.043; L fitted to each
# patch's own profile (its species' area as well as its height, over every scale the patches make:
# sward.patch_stands), to 0.037. The canopy's edge is still a little too opaque there (as, by
# less, for the even field), by more than the stands' own profiles say (open). At 6 samples that
# row's noise was about 0.01: with the leaves at the stems' foot it measured 0.048, at 24 samples
# 0.024 (0.028 without them); the square views take 16.


# dev.py test runs the tests in two processes (pytest-xdist, --dist loadgroup): the tests of one
# set of renders (a module fixture of minutes) run in the same one
SQUARE = pytest.mark.xdist_group("lod_square")


# (in sun only: the square view holds the overcast sky, and the strips' renders of a 102 m field with
# every blade as geometry are the suite's longest)
STRIP_CASES = [f"strip{h}m_{preset}_sun" for h in ("1.1", "6") for preset in ("even", "meadow")]


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    out = tmp_path_factory.mktemp("lod")
    args = lod_compare.parse_args(["--resolution", "96x54", "--samples", "16", "--blocks", "16", "--views", "square",
                                   "--presets", "even", "meadow", "painted", "--flythrough-frames", "3",
                                   "--out", str(out)])
    return lod_compare.compare(args), out


@SQUARE
@pytest.mark.parametrize("case", ["even_sun", "even_overcast", "meadow_sun", "meadow_overcast",
                                  "painted_sun", "painted_overcast"])
def test_the_lod_render_matches_the_all_geometry_render(comparison, case):
    import numpy as np

    result, out = comparison
    figures = result["cases"][case]
    assert figures["mean_abs_diff"] <= IMAGE_GOAL
    rows = np.load(out / f"{case}_rows.npz")
    diff = np.abs(rows["lod"] - rows["geometry"]).max(axis=1)
    assert diff.max() <= ROW_GOAL, json.dumps(figures)
    # grass, not a flat band: the LOD rows below the field's edge are green like the geometry's
    sky = rows["geometry"].mean(axis=1) > 0.3  # rows of sky (bright) in the all-geometry render
    field_rows = np.arange(len(diff)) > int(np.flatnonzero(sky).max()) + 3
    lod = rows["lod"][field_rows]
    assert np.all(lod[:, 1] > lod[:, 0]) and np.all(lod[:, 1] > lod[:, 2])


@pytest.fixture(scope="module")
def strips(tmp_path_factory):
    out = tmp_path_factory.mktemp("lod_strip")
    args = lod_compare.parse_args(["--resolution", "96x54", "--samples", "6", "--views", "strip",
                                   "--heights", "1.1", "6", "--presets", "even", "meadow", "--lights", "sun",
                                   "--flythrough-frames", "0", "--out", str(out)])
    return lod_compare.compare(args), out


@pytest.mark.xdist_group("lod_strip")
@pytest.mark.parametrize("case", STRIP_CASES)
def test_the_lod_holds_from_low_and_high_eyes_for_each_species(strips, case):
    import numpy as np

    result, out = strips
    figures = result["cases"][case]
    assert figures["row_diff_max"] <= ROW_GOAL and figures["mean_abs_diff"] <= IMAGE_GOAL, json.dumps(figures)
    rows = np.load(out / f"{case}_rows.npz")
    grass = lod_compare.grass_rows(rows["geometry"])
    assert grass.sum() > 0.4 * len(grass)  # the field fills the lower part of the frame
    lod = rows["lod"][grass]
    assert np.all(lod[:, 1] > lod[:, 0]) and np.all(lod[:, 1] > lod[:, 2])  # green like the grass
    if "_even_" in case:
        assert figures["row_ratio_max"] <= SEAM_GOAL, json.dumps(figures)
    # the pixels compared (``field_pixels``: whole rows to about 40 m) show the field, none the
    # world's floor beside it, which Blender draws in one flat colour where no grass stands
    geo, field = rows["geometry_image"], rows["field"]
    counted = grass & (np.arange(len(grass)) > len(grass) // 2)  # (compare_images: the rows before the far edge)
    assert field[counted].sum(axis=1).min() >= geo.shape[1] // 6
    assert field[np.flatnonzero(counted)[-1]].all()  # the nearest row whole, more than its middle sixth
    beside = [r for r in np.flatnonzero(counted) if not field[r, 0] and np.abs(geo[r, 0] - geo[r, 1]).max() < 1e-3]
    for r in beside:  # rows whose left edge shows the flat floor
        assert np.abs(geo[r][field[r]] - geo[r, 0]).max(axis=1).min() > 1e-3, r
    if case.startswith("strip6m"):
        assert beside  # from 6 m the floor shows beside the far rows


@SQUARE
@pytest.mark.parametrize("light", ["sun", "overcast"])
def test_a_painted_path_is_bare_ground_near_in_the_card_band_and_far(comparison, light):
    """The path painted from the camera's feet to the far edge: in the LOD render its pixels are
    bare ground at near (blades), middle (cards) and far (canopy) distances, as in the all-geometry
    render, and they match its colour there. Ground and grass told apart by green over red and
    blue: the floor's litter shows 0.007-0.012 in these renders, the grass 0.025-0.07."""
    import numpy as np

    _, out = comparison
    data = np.load(out / f"painted_{light}_rows.npz")
    lod, geo = data["lod_image"], data["geometry_image"]

    def green(image):
        return image[..., 1] - np.maximum(image[..., 0], image[..., 2])

    sky = geo.mean(axis=(1, 2)) > 0.3
    horizon = int(np.flatnonzero(sky).max())
    h = geo.shape[0]
    for name, row in (("near", h - 3), ("middle", (horizon + h) // 2), ("far", horizon + 4)):
        grass = np.median(green(geo[row]))
        path = green(geo[row]) < min(0.015, 0.5 * grass)  # the geometry render's bare ground here
        assert 1 <= path.sum() < 0.5 * path.size, (name, path.sum())
        # (the LOD's path edges blend over a pixel: its mean, not every pixel, is held)
        assert green(lod[row])[path].mean() < 0.5 * grass, (name, green(lod[row])[path], grass)
        assert np.abs(lod[row][path].mean(axis=0) - geo[row][path].mean(axis=0)).max() < 0.04, name


@SQUARE
def test_a_slow_flythrough_does_not_pop(comparison):
    """Frame-to-frame change of the LOD render: no more than that of the all-geometry render
    (within the sampling noise of 16 samples: 25 %)."""
    result, _ = comparison
    fly = result["flythrough"]
    assert fly["flicker_lod"] <= 1.25 * fly["flicker_geometry"], fly
