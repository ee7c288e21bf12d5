"""A meadow, as Blender draws it (issue #34): Add Grass Field grows tussocks, seed heads and
flowers that ride their stems' tips; the Lawn preset is even. Every assertion reads the evaluated
slot meshes (the ``drawn`` fixture) and the UV maps the materials read."""

import bpy
import numpy as np
import pytest


def _counts_variance_over_mean(roots: np.ndarray, square: float = 0.25) -> float:
    """Blades rooted in each square of ``square`` metres over the roots' extent (whole squares
    inside it): the variance of the counts over their mean (1 for roots at random, less for an
    even spread, more for clumps)."""
    lo = roots.min(axis=0) + square
    hi = roots.max(axis=0) - square
    edges = [np.arange(lo[k], hi[k], square) for k in range(2)]
    counts, _, _ = np.histogram2d(roots[:, 0], roots[:, 1], bins=edges)
    return float(counts.var() / counts.mean())


def test_add_grass_field_grows_tussocks_and_the_lawn_preset_is_even(runtime, settle, stems):
    """The roots Blender draws, counted in 0.25 m squares: a meadow's tussocks give counts whose
    variance is at least 1.5 times their mean (grasses grow in clumps); the Lawn preset spreads
    them more evenly than at random (variance below the mean)."""
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(1)
    meadow = _counts_variance_over_mean(stems(item)[:, 0].mean(axis=1)[:, :2])
    assert bpy.ops.windgrass.species_preset(preset="lawn") == {"FINISHED"}
    settle()
    scene.frame_set(2)
    lawn = _counts_variance_over_mean(stems(item)[:, 0].mean(axis=1)[:, :2])
    assert meadow >= 1.5 and lawn < 1.0, (meadow, lawn)


def _widths(strips: np.ndarray) -> np.ndarray:
    return np.linalg.norm(strips[:, :, 1] - strips[:, :, 0], axis=2)


def test_flowers_and_seed_heads_ride_their_stems_tips_every_frame(runtime, settle, stems):
    """Blades with a flower of the strip (head shape "flower") open into a head on their top two
    segments (at least three times the root's width at the joint below the tip, still half of
    that at the tip, where a plain blade tapers to a sixth); seed heads are widest at the joint
    below the tip and close at it. Over frames of wind the widened joints stay the strip's own
    joints: every segment keeps its length (the heads ride the solver's tips, no second body) and
    the tips sway. (Flowers and seed heads that are meshes: test_heads.py.)"""
    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    for row in item.blade.species:
        if row.head_shape in ("daisy", "buttercup"):
            row.head_shape = "flower"
        elif row.head_shape in ("spike", "panicle"):
            row.head_shape = "seed"
    settle()
    n = item.blade.segments
    tips, lengths = [], None
    for frame in (1, 9, 17):
        scene.frame_set(frame)
        strips = stems(item)
        width = _widths(strips)
        flowers = (width[:, n - 1] > 3.0 * width[:, 0]) & (width[:, n] > 1.5 * width[:, 0])
        seeds = (width[:, n - 1] > 1.5 * width[:, 0]) & (width[:, n] < 0.3 * width[:, 0])
        plain = ~flowers & ~seeds
        assert 0.02 < flowers.mean() < 0.2 and 0.02 < seeds.mean() < 0.3, (flowers.mean(), seeds.mean())
        assert np.all(width[plain, n] < 0.3 * width[plain, 0])  # plain blades taper to their tips
        centre = strips.mean(axis=2)
        segment = np.linalg.norm(np.diff(centre, axis=1), axis=2)
        if lengths is None:
            lengths = segment
        else:  # the same blades in the same order (the slots show the same blocks): lengths kept
            np.testing.assert_allclose(segment, lengths, rtol=1e-3, atol=1e-5)
        tips.append(centre[:, n])
    assert np.percentile(np.linalg.norm(tips[1] - tips[0], axis=1), 90) > 0.005  # they sway in the wind


def test_the_heads_carry_their_colours_and_dry_tips_turn_to_straw(runtime):
    """The tint the blade material reads (UV maps wg_tint_rg and wg_tint_bs) at each blade's tip
    corners: the seed heads' colours on the stems that carry one, and straw on some tips, while
    every root corner keeps a species' green. (The flowers, meshes on the tips, carry theirs in
    their own meshes: test_heads.py.)"""
    from windgrass.grass_addon import meadow, presets

    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    scene.frame_set(1)
    n = item.blade.segments
    rows = presets.species_rows("meadow")
    greens = np.array([r["color"] for r in rows])
    flowers = np.array([r["head_color"] for r in rows
                        if r["head_shape"] == "seed" and r["heads"] * r["weight"] >= 0.01])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    tip_colours, root_colours = [], []
    for obj in (o for o in item.collection.objects if o.get("wg_role") == "blades"):
        mesh = obj.evaluated_get(depsgraph).data
        rg = np.empty(len(mesh.loops) * 2, np.float32)
        bs = np.empty(len(mesh.loops) * 2, np.float32)
        mesh.uv_layers["wg_tint_rg"].data.foreach_get("uv", rg)
        mesh.uv_layers["wg_tint_bs"].data.foreach_get("uv", bs)
        colour = np.concatenate([rg.reshape(-1, 2), bs.reshape(-1, 2)[:, :1]], axis=1).reshape(-1, n, 4, 3)
        shown = colour.reshape(len(colour), -1).any(axis=1)
        tip_colours.append(colour[shown, n - 1, 2])  # the top segment's top corner
        root_colours.append(colour[shown, 0, 0])
    tips, roots = np.concatenate(tip_colours), np.concatenate(root_colours)
    assert len(tips) > 1000

    def share_near(colours, target, tolerance=0.02):
        return float((np.abs(colours - target).max(axis=1) < tolerance).mean())

    for colour in flowers:
        assert share_near(tips, colour) > 0.005, colour
    assert share_near(tips, meadow.STRAW, 0.08) > 0.02  # dry tips, straw-coloured (more or less dry)
    assert np.all(np.abs(roots[:, None, :] - greens[None]).max(axis=2).min(axis=1) < 1e-4)


def test_the_far_canopy_is_yellower_where_more_buttercups_grow(runtime, tmp_path):
    """Seen from 30 m straight down, where every blade is far grass (the canopy), the render's
    colour follows the species mix patch by patch: over 3.2 m squares, the more of the blades
    rooted there carry a yellow flower, the redder (yellower) the canopy's green (rank correlation
    at least 0.6), and the quarter of the squares with most flowers is yellower than the quarter
    with fewest. The flowers' share is counted on the field's own blades (its layout)."""
    import stage
    from windgrass.grass_addon import schema
    from windgrass.grass_addon.bridge import properties
    from windgrass.grass_addon.layout import build_layout

    rows = [{"name": "grass", "weight": 0.7, "length": 0.35, "length_variation": 0.05, "width": 0.006,
             "color": (0.08, 0.28, 0.05)},
            {"name": "buttercup", "weight": 0.3, "length": 0.4, "length_variation": 0.05, "width": 0.004,
             "color": (0.1, 0.28, 0.05), "heads": 1.0, "head_color": (0.85, 0.6, 0.02), "head_size": 8.0,
             "head_shape": "flower"}]
    params = schema.defaults().replace({
        "field.blocks_x": 16, "field.blocks_y": 16, "field.patchiness": 1.0, "field.patch_size": 6.0,
        "blade.species": rows, "wind.type": "calm", "wind.gust_waves": 0.0, "lod.blade_near": 0.1,
        "lod.blade_far": 0.2, "lod.card_near": 0.3, "lod.card_far": 0.5, "camera.mode": "fixed",
        "render.engine": "cycles", "render.samples": 8, "render.resolution_x": 64, "render.resolution_y": 64})
    scene = bpy.context.scene
    stage.setup_stage(scene, params)
    cam = scene.camera
    cam.animation_data_clear()
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 25.6
    cam.location, cam.rotation_euler = (0.0, 0.0, 30.0), (0.0, 0.0, 0.0)
    item = properties.add_field(scene, params)
    runtime.build_field(scene, item)
    scene.frame_set(1)
    scene.render.filepath = str(tmp_path / "canopy.png")
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(scene.render.filepath)
    pixels = np.array(image.pixels[:], np.float32).reshape(64, 64, 4)[..., :3]  # row 0 at y = -12.8 m
    bpy.data.images.remove(image)
    redness = (pixels[..., 0] / np.maximum(pixels[..., 1], 1e-6)).reshape(8, 8, 8, 8).mean(axis=(1, 3))

    layout = build_layout(params)
    root = layout.blade_root[:, :2]
    square = np.clip(((root + 12.8) // 3.2).astype(int), 0, 7)
    flowers = np.zeros((8, 8))
    blades = np.zeros((8, 8))
    np.add.at(flowers, (square[:, 1], square[:, 0]), layout.blade_flower > 0)
    np.add.at(blades, (square[:, 1], square[:, 0]), 1.0)
    share = (flowers / blades).ravel()
    red = redness.ravel()
    ranks = [np.argsort(np.argsort(v)) for v in (share, red)]
    assert share.max() > 2.0 * share.min()  # the patches do change the mix
    assert np.corrcoef(*ranks)[0, 1] >= 0.6, (share.round(2), red.round(3))
    most, fewest = share >= np.percentile(share, 75), share <= np.percentile(share, 25)
    assert red[most].mean() > 1.05 * red[fewest].mean(), (red[most].mean(), red[fewest].mean())


def test_a_lawn_reads_as_green_turf_not_bare_ground(rendered, tmp_path):
    """Issue #34: the Lawn preset drew its few hundred blades a square metre over the meadow's brown
    thatch, and from 1.1 m the lawn came out dark olive (display colour 46, 55, 33: green only 1.18
    times red). A lawn's floor is its dense living turf (``field.floor = "turf"``): the render below
    the horizon is green (green at least 1.4 times red, as display values), far greener than the
    same blades over thatch."""
    from windgrass.grass_addon import presets, schema

    def render(floor: str) -> np.ndarray:
        params = presets.apply_preset(schema.defaults(), "lawn").replace({
            "field.blocks_x": 8, "field.blocks_y": 8, "field.floor": floor, "wind.type": "calm",
            "camera.mode": "fixed", "camera.position": (0.0, -4.0, 1.1), "camera.target": (0.0, 3.0, 0.0),
            "render.engine": "cycles", "render.samples": 8, "render.resolution_x": 64,
            "render.resolution_y": 36})
        pixels = rendered(params, 1, tmp_path / f"{floor}.png")  # row 0 at the bottom
        return pixels[:12].reshape(-1, 3).mean(axis=0)  # the lowest third: the lawn near the camera

    turf, thatch = render("turf"), render("thatch")
    assert turf[1] >= 1.4 * turf[0] and turf[1] > turf[2], turf
    assert turf[1] / turf[0] >= 1.2 * thatch[1] / thatch[0], (turf, thatch)


def test_pressed_grass_lies_along_the_track_and_stays_green(rendered, tmp_path, stems):
    """Issue #34 item 4: grass flattened by a collider looked like bare ground. A ball 0.7 m wide
    rolls along x through the default meadow (calm air), seen a second later from 1.6 m: the blades
    rooted on its track lie down along it (tips at most half as high as the untouched meadow's,
    pointing the way it rolled), and the pressed band renders as green as the untouched meadow in
    the same rows (green over red, as display values, at least 0.95 of its ratio and 1.1; the thatch
    floor that bare ground would show is 0.92), not as the floor."""
    from pathlib import Path

    from windgrass.grass_addon import schema, sward

    scene_file = Path(__file__).resolve().parents[2] / "scenes" / "default.toml"
    rolled = schema.load_toml(scene_file).replace({
        "field.blocks_x": 6, "field.blocks_y": 6, "wind.type": "calm", "wind.speed": 0.0, "wind.turbulence": 0.0,
        "interaction.recovery": 10.0, "camera.mode": "fixed", "camera.position": (0.0, -2.0, 1.6),
        "camera.target": (0.0, 1.0, 0.0), "camera.fov": 50.0, "render.engine": "cycles", "render.samples": 8,
        "render.resolution_x": 96, "render.resolution_y": 54, "render.motion_blur": False,
        "interaction.colliders": [{"shape": "sphere", "radius": 0.35,
                                   "path": [{"time": 0.0, "position": [-5.0, 0.5, 0.35]},
                                            {"time": 4.0, "position": [5.0, 0.5, 0.35]}]}]})
    plain = rendered(rolled.replace({"interaction.colliders": []}), 72, tmp_path / "plain.png")
    pressed = rendered(rolled, 72, tmp_path / "pressed.png")  # 3 s: the ball is 2.5 m past x = 0
    item = bpy.context.scene.windgrass.fields[0]
    strips = stems(item)
    roots, tips = strips[:, 0].mean(axis=1), strips[:, -1].mean(axis=1)
    lean = tips - roots
    track = (np.abs(roots[:, 1] - 0.5) < 0.15) & (np.abs(roots[:, 0]) < 1.5)
    aside = (np.abs(roots[:, 1] - 2.0) < 0.5) & (np.abs(roots[:, 0]) < 1.5)
    assert track.sum() > 50 and aside.sum() > 50
    assert np.median(lean[track, 2]) < 0.5 * np.median(lean[aside, 2]), (np.median(lean[track, 2]),
                                                                           np.median(lean[aside, 2]))
    assert np.median(lean[track, 0]) > 2.0 * np.median(np.abs(lean[track, 1])) > 0.0  # along +x, the ball's way
    # the pressed band: the rows the ball changed most (display values, the middle half of the columns)
    change = np.abs(pressed - plain)[:, 24:72].mean(axis=(1, 2))
    band = change > 0.5 * change.max()
    colour = pressed[band][:, 24:72].reshape(-1, 3).mean(axis=0)
    untouched = plain[band][:, 24:72].reshape(-1, 3).mean(axis=0)
    thatch = np.array(sward.THATCH_COLOUR) ** (1 / 2.2)  # what bare ground would show, as a display colour
    assert colour[1] / colour[0] >= max(1.1, 1.1 * thatch[1] / thatch[0], 0.95 * untouched[1] / untouched[0]), \
        (colour, untouched)
    assert colour[1] > colour[2]


@pytest.mark.parametrize("blocks", [8, 16])
def test_the_cards_carry_each_of_the_fields_flowers(runtime, blocks, settle):
    """The cards' image (the atlas Blender packs and the card material reads) shows every flower
    of Add Grass Field's meadow, a buttercup's yellow and a daisy's white, on its field (8 x 8
    blocks) and on one of 16 x 16: the cards stand for a few dozen of the field's blades, and
    the first cells of the larger field's sample held daisies alone, so its card band lost the
    buttercups (issue #34)."""
    from windgrass.grass_addon import presets
    from windgrass.grass_addon.bridge import owned

    assert bpy.ops.windgrass.field_add() == {"FINISHED"}
    scene = bpy.context.scene
    item = scene.windgrass.fields[0]
    if item.field.blocks_x != blocks:
        item.field.blocks_x = item.field.blocks_y = blocks  # as in the panel
        settle()
    scene.frame_set(1)
    image = owned.registered(item)[owned.ROLE_CARD_IMAGE]
    w, h = image.size
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)
    srgb = pixels[..., :3]
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)[pixels[..., 3] > 0.5]
    hue = linear / np.maximum(linear.max(axis=1, keepdims=True), 1e-6)  # colour over its brightest channel
    for row in presets.species_rows("meadow"):
        if row.get("head_shape") != "flower" or row.get("heads", 0.0) <= 0.0:
            continue
        target = np.asarray(row["head_color"]) / max(row["head_color"])
        shown = int((np.abs(hue - target).max(axis=1) < 0.06).sum())
        assert shown >= 20, (row["name"], shown)  # a flower is some hundreds of pixels


def test_the_far_canopy_seen_from_above_shows_the_flowers_at_their_share(rendered, tmp_path):
    """Issue #59: a drone saw no flower in the far canopy. Straight down from 3 m over a field
    drawn as far canopy alone (LOD distances under a metre), of grass, buttercups (yellow, 30 %
    of the stems) and daisies (white, 20 %), every one in flower, 3.2 cm wide: yellow and white
    specks cover about the ground's share their flowers cover (each stems per m² x share x
    pi r^2, by hand: 7.2 % and 4.8 %; within 0.4-2.5 times, lit and antialiased), and the same
    field without flowers shows none."""
    from windgrass.grass_addon import schema

    def rows(heads: float) -> list:
        flower = {"length": 0.4, "length_variation": 0.05, "width": 0.004, "color": (0.1, 0.28, 0.05),
                  "heads": heads, "head_size": 8.0, "head_shape": "flower"}
        return [{"name": "grass", "weight": 0.5, "length": 0.35, "length_variation": 0.05, "width": 0.006,
                 "color": (0.08, 0.28, 0.05)},
                {**flower, "name": "buttercup", "weight": 0.3, "head_color": (0.85, 0.6, 0.02)},
                {**flower, "name": "daisy", "weight": 0.2, "head_color": (0.8, 0.8, 0.75)}]

    params = schema.defaults().replace({
        "field.blocks_x": 8, "field.blocks_y": 8, "field.blades_per_cell": 3, "field.cell_size": 0.1,
        "field.patchiness": 0.0, "blade.species": rows(1.0), "wind.type": "calm", "wind.gust_waves": 0.0,
        "lod.blade_near": 0.1, "lod.blade_far": 0.2, "lod.card_near": 0.3, "lod.card_far": 0.5,
        "camera.mode": "fixed", "camera.position": (0.0, 0.0, 3.0), "camera.target": (0.001, 0.0, 0.0),
        "render.engine": "cycles", "render.samples": 16, "render.resolution_x": 200, "render.resolution_y": 200})
    per_m2 = 3 / 0.1 ** 2
    area = np.pi * (0.5 * 8.0 * 0.004) ** 2
    expected = {"yellow": per_m2 * 0.3 * area, "white": per_m2 * 0.2 * area}

    def shares(px) -> dict:  # (pixels at least half as bright as a whole flower's: half covered or more)
        yellowish = (px[..., 2] < 0.3 * px[..., 0]) & (px[..., 1] > 0.45 * px[..., 0])
        whitish = np.ptp(px, axis=2) < 0.25 * px.max(axis=2)
        full = np.percentile(px.max(axis=2), 99.5)
        yellow = yellowish & (px[..., 0] > 0.5 * full)
        white = whitish & (px.min(axis=2) > 0.5 * full)
        return {"yellow": float(yellow.mean()), "white": float(white.mean())}

    flowered = shares(rendered(params, 1, tmp_path / "flowers.png"))
    bare = shares(rendered(params.replace({"blade.species": rows(0.0)}), 1, tmp_path / "bare.png"))
    for colour, share in expected.items():
        assert 0.4 * share < flowered[colour] < 2.5 * share, (colour, flowered, expected)
        assert bare[colour] < 0.1 * share, (colour, bare)
