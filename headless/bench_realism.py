"""How much the default scene reads as a meadow in wind, in numbers; prints ONE JSON object.

    python headless/bench_realism.py [--image PNG] [--loop S] [--json]     (dev.py bench --realism)

* clumps: blades rooted in each 0.25 m square of a meadow (the "meadow" preset) and of a lawn
  (the "lawn" preset): the counts' variance over their mean (1 at random, less even, more clumped);
* sway: each species of the meadow preset: its tip sway in gusty wind at 4 and 8 m/s (60 s of eight seeds' fields, the
  engine's cell bends at 24 fps, cells where the species is the most blades): the frequency where the sway's
  spectrum peaks above 0.3 Hz and the peak's height over the spectrum's mean from 0.1 to 0.3 Hz;
  and the grass's own sway: where the tip's spectrum over that of the gusts it meets (the
  turbulence at its cell) peaks between 0.3 and 3 Hz (its resonance) and that gain over the gain at
  0.1-0.3 Hz;
* waves: the downwind speed of the gust waves (wind.displacement over 10 s) against the mean wind;
* ``--loop S``: the sway and the waves with ``simulation.loop = S`` (the same wind, looped: the
  gusts the sway meets are then the looped wind less its mean), to set beside a run without;
* image (``--image``, a rendered frame of scenes/default.toml, e.g. renders/frame_0012.png): the
  near grass (the image's lowest fifth): its hue's spread (the 5th to the 95th percentile, in
  degrees) and the share of its pixels that are not green (hue outside 60-170 degrees); the far
  band (the rows from the horizon down to a tenth of the image): how much its 8 x 8-pixel tiles
  differ in brightness (their standard deviation over their mean), over the whole band (the band's
  darkening towards the camera included, as issue #34 measured it) and ``_across`` each row of
  tiles (the field's own variety: patches, tussocks, gusts), and how much their hue spreads across
  each row (5th to 95th percentile, degrees: the patches' species colours and flowers at distance).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402

common.load()
from windgrass.grass_addon import presets, schema  # noqa: E402
from windgrass.grass_addon.field import GrassField  # noqa: E402
from windgrass.grass_addon.layout import build_layout  # noqa: E402

SQUARE = 0.25  # m: the squares the roots are counted in
SWAY_SECONDS = 60.0
SWAY_SEEDS = (7, 8, 9, 10, 11, 12, 13, 14)
FPS = 24
LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of RGB


def clump_ratio(preset: str) -> float:
    params = presets.apply_preset(schema.loads_toml(_default_scene()), preset).replace(
        {"field.blocks_x": 4, "field.blocks_y": 4})
    roots = build_layout(params).blade_root[:, :2]
    edges = np.arange(roots.min() + SQUARE, roots.max() - SQUARE, SQUARE)
    counts, _, _ = np.histogram2d(roots[:, 0], roots[:, 1], bins=[edges, edges])
    return round(float(counts.var() / counts.mean()), 2)


def _default_scene() -> str:
    return (Path(__file__).resolve().parents[1] / "scenes" / "default.toml").read_text()


LOOP = {"simulation.loop": 0.0}  # (main sets it from --loop)


def sway(speed: float) -> dict:
    """{species: {peak_hz, peak_over_slow}} of the tip sway at mean wind ``speed``: the spectra of
    SWAY_SEEDS fields (one 3.2 m field's gusts are one sample of the wind: its spectrum's bumps are
    chance), each cell's from SWAY_SECONDS of its bend, averaged over the cells where the species is
    the most blades."""
    params = presets.apply_preset(schema.loads_toml(_default_scene()), "meadow").replace(
        {"field.blocks_x": 2, "field.blocks_y": 2, "wind.speed": speed, "wind.turbulence": 0.3 * speed,
         "wind.gust_waves": 0.0, "lod.enabled": False, "render.fps": FPS, **LOOP})
    frames = int(SWAY_SECONDS * FPS)
    hz = np.fft.rfftfreq(frames, 1.0 / FPS)
    angle = np.radians(params.wind.direction)
    along = np.array([np.cos(angle), np.sin(angle)])
    names = [row["name"] for row in params.species()]
    spectra: dict[str, list] = {name: [] for name in names}
    for seed in SWAY_SEEDS:
        field = GrassField(params.replace({"field.seed": seed}))
        tips = np.empty((frames, field.layout.n_cells), np.float64)
        gusts = np.empty_like(tips)
        for f in range(frames):
            tips[f] = field.seek(f + 1).bend.sum(axis=1) @ along  # the tip's tilt downwind (radians)
            gusts[f] = _gusts_met(field.sim.wind, (f + 1) / FPS) @ along  # the gusts it meets (m/s)
        power = _power(tips, frames)
        forcing = _power(gusts, frames)
        layout = field.layout
        num = layout.blades_per_cell
        kinds = layout.blade_species.reshape(-1, num)
        dominant = np.array([np.bincount(k, minlength=len(names)).argmax() for k in kinds])
        cell_of = layout.blade_cell.reshape(-1, num)[:, 0]
        for k, name in enumerate(names):
            mine = cell_of[dominant == k]
            if mine.size:
                spectra[name].append((power[:, mine].mean(axis=1), forcing[:, mine].mean(axis=1)))
    out = {}
    fast, slow_band = hz > 0.3, (hz >= 0.1) & (hz <= 0.3)
    for name, rows in spectra.items():
        if not rows:
            continue
        spectrum = np.mean([r[0] for r in rows], axis=0)
        transfer = _smooth(spectrum) / np.maximum(_smooth(np.mean([r[1] for r in rows], axis=0)), 1e-30)
        peak = int(np.flatnonzero(fast)[spectrum[fast].argmax()])
        band = (hz > 0.3) & (hz < 3.0)
        own = int(np.flatnonzero(band)[transfer[band].argmax()])
        out[name] = {"peak_hz": round(float(hz[peak]), 2),
                     "peak_over_slow": round(float(spectrum[peak] / spectrum[slow_band].mean()), 3),
                     "resonance_hz": round(float(hz[own]), 2),
                     "resonance_gain": round(float(transfer[own] / transfer[slow_band].mean()), 2)}
    return out


def _gusts_met(wind, t: float) -> np.ndarray:
    """The wind's moving part at ``t`` at every cell: the turbulence (a looped wind: the looped
    wind less its mean)."""
    if not wind.loop:
        return wind.turbulence(t)
    return wind.sample(t) - np.asarray(wind._mean_vector(t), np.float32)


def _power(series: np.ndarray, frames: int) -> np.ndarray:
    """Power spectra (bins, columns) of the columns of ``series`` (Hann window)."""
    centred = series - series.mean(axis=0)
    return np.abs(np.fft.rfft(centred * np.hanning(frames)[:, None], axis=0)) ** 2


def _smooth(spectrum: np.ndarray, bins: int = 9) -> np.ndarray:
    """A spectrum averaged over ``bins`` neighbouring bins (0.15 Hz at 60 s)."""
    return np.convolve(spectrum, np.ones(bins) / bins, mode="same")


def wave_speed(speed: float) -> float:
    params = schema.loads_toml(_default_scene()).replace({"wind.speed": speed, **LOOP})
    field = GrassField(params.replace({"field.blocks_x": 2, "field.blocks_y": 2}))
    moved = np.linalg.norm(np.asarray(field.wind.displacement(10.0)) - np.asarray(field.wind.displacement(0.0)))
    return round(float(moved / 10.0), 2)


def image_figures(path: Path) -> dict:
    from PIL import Image

    rgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    h = rgb.shape[0]
    near = rgb[int(0.8 * h):].reshape(-1, 3)
    hue = _hue(near)
    green = (hue >= 60.0) & (hue <= 170.0)
    spread = np.percentile(hue[green], 95) - np.percentile(hue[green], 5)
    lum = rgb @ LUMA
    horizon = int(np.argmax(np.abs(np.diff(lum.mean(axis=1))) > 0.02)) + 2
    rows = max(8, h // 10)
    band = rgb[horizon:horizon + rows]
    band = band[: band.shape[0] // 8 * 8, : band.shape[1] // 8 * 8]
    colours = band.reshape(band.shape[0] // 8, 8, band.shape[1] // 8, 8, 3).mean(axis=(1, 3))
    tiles = colours @ LUMA
    # across each row of tiles (the band darkens towards the camera: that is not the field's variety)
    across = float(np.mean(tiles.std(axis=1) / tiles.mean(axis=1)))
    hues = _hue(colours.reshape(-1, 3)).reshape(tiles.shape)
    hue_across = float(np.mean(np.percentile(hues, 95, axis=1) - np.percentile(hues, 5, axis=1)))
    return {"near_hue_spread_deg": round(float(spread), 1), "near_not_green_share": round(float(1 - green.mean()), 4),
            "far_band_tile_contrast": round(float(tiles.std() / tiles.mean()), 4),
            "far_band_tile_contrast_across": round(across, 4),
            "far_band_tile_hue_spread_across_deg": round(hue_across, 1),
            "far_band_rows": [horizon, horizon + rows]}


def _hue(rgb: np.ndarray) -> np.ndarray:
    """Hue in degrees (0 red, 120 green, 240 blue) of linear or display RGB rows."""
    r, g, b = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    mx, mn = rgb.max(axis=1), rgb.min(axis=1)
    d = np.where(mx - mn > 1e-9, mx - mn, 1.0)
    h = np.where(mx == r, (g - b) / d % 6.0, np.where(mx == g, (b - r) / d + 2.0, (r - g) / d + 4.0))
    return np.where(mx - mn > 1e-9, 60.0 * h, -1.0)


def main(argv=None) -> int:
    parser = common.parser(__doc__)
    parser.add_argument("--image", type=Path, help="a rendered frame of scenes/default.toml (PNG)")
    parser.add_argument("--loop", type=float, default=0.0, help="the sway and waves with simulation.loop = S s")
    args = parser.parse_args(argv)
    LOOP["simulation.loop"] = args.loop
    result = {"clumps_variance_over_mean": {"meadow": clump_ratio("meadow"), "lawn": clump_ratio("lawn")},
              "sway": {"4 m/s": sway(4.0), "8 m/s": sway(8.0)},
              "wave_speed_m_s": {"4 m/s": wave_speed(4.0), "8 m/s": wave_speed(8.0)}}
    if args.image is not None:
        if not args.image.is_file():
            print(f"bench_realism.py: error: --image {args.image} is not a file (valid: a PNG)", file=sys.stderr)
            return 2
        result["image"] = image_figures(args.image)
    common.emit(result, args)
    return 0


if __name__ == "__main__":
    common.finish(main())
