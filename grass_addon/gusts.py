"""Gust waves: patches of stronger and weaker wind tens of metres wide, carried downwind.

In a real meadow the wind is most visible far away: gusts run across the field as waves of
lighter and darker grass. The turbulence of eq 13 is finer than a metre, so at a distance it
averages out. ``wind.gust_waves`` adds a large, smooth pattern that scales the mean wind
(``1 + gust_waves (2 g - 1)``, g in 0..1) and travels with it (frozen, like the turbulence):

* the engine bends the near grass by it (``WindField``);
* the cards and the far canopy brighten and darken by the same pattern at their place and time
  (a packed image of it, ``pattern``, read by their materials at the mean wind's displacement),
  so a gust that crosses the near grass is seen travelling on to the horizon with no simulation
  of the far field.

The pattern is one tile of ``TILE_PIXELS`` squared values (a Gaussian random field of the seed,
low-pass filtered in Fourier space so it tiles), ``TILE_SIZES`` gust sizes wide; it is sampled
bilinearly between pixel centres and wraps, exactly as Blender's Linear / Repeat image texture.
Its patches are ``wind.gust_stretch`` times longer across the wind (``wind.direction``) than along
it: a gust over a field runs as a band across it, its front broad and its depth short, as the waves
seen sweeping over a meadow from above.
"""

from __future__ import annotations

import numpy as np

from .schema import Params

TILE_PIXELS = 64
TILE_SIZES = 8.0  # a tile spans this many gust sizes (wind.gust_wave_size)
GUST_PURPOSE = 29  # np.random.default_rng([seed, 29]) draws the pattern


def tile_metres(params: Params) -> float:
    return TILE_SIZES * float(params.wind.gust_wave_size)


def pattern(seed: int, direction: float = 0.0, stretch: float = 1.0) -> np.ndarray:
    """(TILE_PIXELS, TILE_PIXELS) float32 in [0, 1], mean 0.5: smooth patches about
    TILE_PIXELS / TILE_SIZES pixels deep along the wind blowing towards ``direction`` (degrees
    from +X, counter-clockwise) and ``stretch`` times that across it, tiling without a seam (row 0
    is y = 0; row index y, column index x)."""
    n = TILE_PIXELS
    white = np.random.default_rng([int(seed), GUST_PURPOSE]).standard_normal((n, n))
    k = np.fft.fftfreq(n) * n  # cycles per tile
    angle = np.radians(float(direction))
    ky, kx = k[:, None], k[None, :]
    along = kx * np.cos(angle) + ky * np.sin(angle)  # frequencies along the wind
    across = -kx * np.sin(angle) + ky * np.cos(angle)  # and across it: slower there (bands across the wind)
    k2 = along ** 2 + (float(stretch) * across) ** 2
    cutoff = 0.5 * TILE_SIZES  # patches of one gust size: half a cycle each
    field = np.real(np.fft.ifft2(np.fft.fft2(white) * np.exp(-k2 / (cutoff * cutoff))))
    field = (field - field.mean()) / max(field.std(), 1e-12)
    return np.clip(0.5 + field / 4.0, 0.0, 1.0).astype(np.float32)  # +-2 sigma -> 0 .. 1


def sample(tile: np.ndarray, xy: np.ndarray, metres: float, offset=(0.0, 0.0)) -> np.ndarray:
    """(m,) float32: the pattern at points ``xy - offset`` (m, 2), the tile spanning ``metres``:
    bilinear between pixel centres, wrapping (Blender's Linear interpolation, Repeat extension).
    ``sample_twin`` is the same, written plainly. (Run every frame on the window's cells: each
    axis apart in contiguous arrays; the four neighbours read from a copy of the tile with its
    first row and column repeated after its last, by flat index; a power-of-two tile wraps by a
    bit mask.)"""
    xy = np.asarray(xy, np.float64)
    ix, fx = _axis(tile, xy[:, 0], metres, float(offset[0]))
    at, fy = _axis(tile, xy[:, 1], metres, float(offset[1]))
    return _blend(tile, at, ix, fx, fy)


def sample_blocks(tile: np.ndarray, xs: np.ndarray, ys: np.ndarray, metres: float, offset=(0.0, 0.0)) -> np.ndarray:
    """``sample`` at the cells of blocks that are grids, block b's cell (r, c) at (xs[b, c],
    ys[b, r]): (blocks, rows, cols) float32, the same bits as ``sample`` at those points, with
    each column's and row's pixel and fraction found once."""
    blocks, n = xs.shape
    ix, fx = _axis(tile, np.asarray(xs, np.float64).ravel(), metres, float(offset[0]))
    at, fy = _axis(tile, np.asarray(ys, np.float64).ravel(), metres, float(offset[1]))
    return _blend(tile, at.reshape(blocks, n, 1), ix.reshape(blocks, 1, n), fx.reshape(blocks, 1, n),
                  fy.reshape(blocks, n, 1))


def _axis(tile: np.ndarray, p: np.ndarray, metres: float, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """(pixel index wrapped, fraction float32) of coordinates ``p`` (float64) along one axis."""
    n = tile.shape[0]
    p = p - offset
    p *= n / metres
    p -= 0.5
    corner = np.floor(p)
    p -= corner
    i = corner.astype(np.int64)
    if n & (n - 1) == 0:
        i &= n - 1
    else:
        i %= n
    return i, p.astype(np.float32)


def _blend(tile: np.ndarray, iy: np.ndarray, ix: np.ndarray, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    """Bilinear blend of the four pixels from (ix, iy) (arrays that broadcast together)."""
    n = tile.shape[0]
    wrapped = np.empty((n + 1, n + 1), np.float32)
    wrapped[:n, :n] = tile
    wrapped[n, :n] = tile[0]
    wrapped[:, n] = wrapped[:, 0]
    flat = wrapped.ravel()
    at = iy * (n + 1)
    at = at + ix  # (x0, y0); x0 + 1 is at + 1, y0 + 1 is at + n + 1
    low = flat.take(at)
    low += (flat.take(at + 1) - low) * fx
    high = flat.take(at + n + 1)
    high += (flat.take(at + n + 2) - high) * fx
    high -= low
    high *= fy
    high += low
    return high


def sample_twin(tile: np.ndarray, xy: np.ndarray, metres: float) -> np.ndarray:
    """``sample``, plainly: the four pixels around each point on the wrapped tile, weighted."""
    n = tile.shape[0]
    p = np.asarray(xy, np.float64) * (n / metres) - 0.5
    corner = np.floor(p)
    f = (p - corner).astype(np.float32)
    i = corner.astype(np.int64) % n
    j = (i + 1) % n
    fx, fy = f[:, 0], f[:, 1]
    x00, x10 = tile[i[:, 1], i[:, 0]], tile[i[:, 1], j[:, 0]]
    x01, x11 = tile[j[:, 1], i[:, 0]], tile[j[:, 1], j[:, 0]]
    low = x00 + (x10 - x00) * fx
    return low + (x01 + (x11 - x01) * fx - low) * fy
