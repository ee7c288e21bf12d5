"""The grass-clump texture of the billboard cards (paper III.B), generated with numpy.

The paper covers each card with a "semi-transparency grass pack texture". The add-on ships no
image files: ``draw_grass_clump`` paints one from tapered, slightly curved blades, and
``ensure_card_image`` turns it into a packed Blender image (it survives save and reopen).
"""

from __future__ import annotations

import numpy as np

# Purpose number of the texture's random stream (np.random.default_rng([seed, PURPOSE, ...])).
RNG_PURPOSE_CARD_TEXTURE = 7301

# Colours in linear RGB: the blade base is darker and browner than the tip (self-shadowing
# inside a clump), the tip takes the species colour.
BASE_COLOUR = np.array((0.035, 0.06, 0.015), dtype=np.float32)
TIP_COLOUR = np.array((0.16, 0.36, 0.07), dtype=np.float32)


def draw_grass_clump(size: int = 256, blades: int = 40, seed: int = 0) -> np.ndarray:
    """RGBA image of a clump of grass blades, shape (size, size, 4) float32, straight alpha.

    Row 0 is the bottom of the image (Blender's pixel order), so the roots sit on v = 0 and the
    tips point to v = 1. Every blade is a tapered strip whose centre line bends quadratically
    (like a cantilever under its own weight, eq 6) towards a random side. Blades are drawn back
    to front with the "over" operator; edges are anti-aliased over one pixel.
    """
    if size < 8:
        raise ValueError(f"texture size {size} is too small (valid: >= 8 pixels)")
    rng = np.random.default_rng([seed, RNG_PURPOSE_CARD_TEXTURE, size, blades])
    rgb = np.zeros((size, size, 3), dtype=np.float32)
    alpha = np.zeros((size, size), dtype=np.float32)
    y = (np.arange(size, dtype=np.float32) + 0.5) / size  # v of each row
    x = (np.arange(size, dtype=np.float32) + 0.5) / size  # u of each column
    pixel = 1.0 / size

    root_x = rng.uniform(0.06, 0.94, blades).astype(np.float32)
    height = rng.uniform(0.5, 0.97, blades).astype(np.float32)
    lean = rng.normal(0.0, 0.12, blades).astype(np.float32)  # tip offset as a fraction of the width
    width = rng.uniform(0.018, 0.034, blades).astype(np.float32)  # root width
    tint = rng.uniform(0.75, 1.25, (blades, 1)).astype(np.float32)  # per-blade value variation
    yellow = rng.uniform(0.0, 0.35, (blades, 1)).astype(np.float32)  # some blades drier
    order = np.argsort(rng.random(blades))  # random depth order
    for k in order:  # one-off at creation, not a per-frame path
        t = np.clip(y / height[k], 0.0, 1.0)  # position along the blade, per row
        inside_rows = y <= height[k]
        centre = root_x[k] + lean[k] * t * t  # quadratic bend of the centre line
        half = 0.5 * width[k] * (1.0 - t) ** 0.8 + 0.25 * pixel  # taper to a point
        dist = np.abs(x[None, :] - centre[:, None])  # (rows, cols)
        a = np.clip((half[:, None] - dist) / pixel + 0.5, 0.0, 1.0)
        a *= inside_rows[:, None]
        colour = BASE_COLOUR + (TIP_COLOUR - BASE_COLOUR) * np.sqrt(t)[:, None]  # root -> tip
        colour = colour * tint[k] + yellow[k] * np.array((0.10, 0.06, 0.0), dtype=np.float32) * t[:, None]
        a3 = a[..., None]
        rgb = colour[:, None, :] * a3 + rgb * (1.0 - a3)
        alpha = a + alpha * (1.0 - a)
    # Straight (un-premultiplied) colour where coverage is partial.
    covered = alpha > 1e-6
    rgb[covered] /= np.maximum(alpha[covered][:, None], 1e-6)
    image = np.empty((size, size, 4), dtype=np.float32)
    image[..., :3] = np.clip(rgb, 0.0, 1.0)
    image[..., 3] = alpha
    return np.ascontiguousarray(image)


def linear_to_srgb(rgb: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1), float32."""
    rgb = np.clip(rgb, 0.0, 1.0)
    return np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055).astype(np.float32)


def ensure_card_image(name: str, size: int = 256, seed: int = 0):
    """The packed Blender image of the card texture named ``name``; created once."""
    import bpy

    image = bpy.data.images.get(name)
    if image is not None and tuple(image.size) == (size, size) and image.packed_file is not None:
        return image
    if image is not None:
        bpy.data.images.remove(image)
    pixels = draw_grass_clump(size=size, seed=seed)
    image = bpy.data.images.new(name, width=size, height=size, alpha=True)
    image.colorspace_settings.name = "sRGB"
    # A byte image stores its colour-space values as they are: encode linear RGB to sRGB.
    pixels = pixels.copy()
    pixels[..., :3] = linear_to_srgb(pixels[..., :3])
    image.pixels.foreach_set(pixels.ravel())
    image.alpha_mode = "STRAIGHT"
    image.pack()
    return image
