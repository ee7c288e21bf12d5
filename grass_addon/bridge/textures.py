"""The cards' texture in Blender (paper III.B): the atlas of the field's own blades, packed.

The paper covers each card with a "semi-transparency grass pack texture". The add-on ships no
image files: ``atlas.card_atlas`` paints the blades of sample cells of the field (their
shapes, coverage and colours) and ``paint_card_image`` writes it into a packed Blender image (it
survives save and reopen), again whenever the parameters it depends on change.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from .. import atlas, edit_parts, gusts, interaction, sward
from ..schema import Params

DIGEST_KEY = "wg_atlas"  # custom property of the image: the digest of what it was painted from


def linear_to_srgb(rgb: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1), float32."""
    rgb = np.clip(rgb, 0.0, 1.0)
    return np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055).astype(np.float32)


def atlas_digest(params: Params) -> str:
    """What the atlas depends on: the field's blades, their colours and the cards' width (not the
    wind, the solver, LOD distances: ``edit_parts``)."""
    inputs = [edit_parts.digest_of(params, (edit_parts.LAYOUT, edit_parts.LOOK)), params.lod.card_width,
              atlas.CARD_VARIANTS, atlas.CARD_PIXELS]
    return hashlib.sha1(json.dumps(inputs).encode()).hexdigest()[:16]


def ensure_card_image(name: str):
    """The packed Blender image named ``name`` (created once, the atlas's size; painted by
    ``paint_card_image``)."""
    import bpy

    width, height = atlas.CARD_VARIANTS * atlas.CARD_PIXELS, atlas.CARD_PIXELS
    image = bpy.data.images.get(name)
    if image is not None and tuple(image.size) == (width, height) and image.packed_file is not None:
        image.alpha_mode = "CHANNEL_PACKED"
        return image
    if image is not None:
        bpy.data.images.remove(image)
    image = bpy.data.images.new(name, width=width, height=height, alpha=True)
    image.colorspace_settings.name = "sRGB"
    # colour and alpha kept apart: where no blade covers the card the colour stays the grass's
    # (premultiplied storage would make it black; see atlas.card_atlas)
    image.alpha_mode = "CHANNEL_PACKED"
    image.pack()
    return image


def paint_card_image(image, params: Params, own=None) -> None:
    """Paint the atlas of ``params`` (with the artist's plants ``own``, ``plants.Plants``) into
    ``image`` unless it already shows it."""
    digest = atlas_digest(params) + (repr(own) if own else "")
    if image.get(DIGEST_KEY) == digest:
        return
    pixels = atlas.card_atlas(params, own=own) if own else atlas.card_atlas(params)
    # A byte image stores its colour-space values as they are: encode linear RGB to sRGB.
    pixels[..., :3] = linear_to_srgb(pixels[..., :3])
    image.pixels.foreach_set(np.ascontiguousarray(pixels).ravel())
    image.pack()
    image[DIGEST_KEY] = digest


GUST_KEY = "wg_gusts"  # custom property of the gust image: the seed and wind direction it was painted from


def ensure_gust_image(name: str):
    """The packed float image of the gust waves' pattern (``gusts.pattern``), linear values."""
    return _grey_image(name, gusts.TILE_PIXELS)


def _grey_image(name: str, n: int | None, float_buffer: bool = True, alpha: bool = False):
    """The packed n x n image ``name`` (Non-Color: linear values; float, or bytes), made again when
    missing, of another size (``n`` None: any; made 1 x 1) or kind, or unpacked. ``alpha``: its alpha
    is a channel of its own (channel packed: a fourth value, never mixed into the colours)."""
    import bpy

    image = bpy.data.images.get(name)
    if (image is not None and (n is None or tuple(image.size) == (n, n)) and image.is_float == float_buffer
            and image.packed_file is not None and (image.alpha_mode == "CHANNEL_PACKED") == alpha):
        return image
    if image is not None:
        bpy.data.images.remove(image)
    image = bpy.data.images.new(name, width=n or 1, height=n or 1, alpha=alpha, float_buffer=float_buffer)
    image.colorspace_settings.name = "Non-Color"
    if alpha:
        image.alpha_mode = "CHANNEL_PACKED"
    image.pack()
    return image


def _write_grey(image, values: np.ndarray, alpha: np.ndarray | None = None) -> None:
    """Write ``values`` (rows from the bottom, as Blender's pixel rows; (h, w), or (h, w, 3) colours)
    into ``image``'s R, G and B (alpha 1, or ``alpha`` (h, w)) and pack it: a packed image is saved
    with the file, not a modified image to Blender."""
    rgba = np.ones((*values.shape[:2], 4), np.float32)
    rgba[..., :3] = values[..., None] if values.ndim == 2 else values
    if alpha is not None:
        rgba[..., 3] = alpha
    image.pixels.foreach_set(rgba.ravel())
    image.pack()


def paint_gust_image(image, params: Params) -> None:
    """Write the gust pattern of the field's seed, wind direction and stretch into ``image`` unless
    it already holds it."""
    seed, direction, stretch = int(params.field.seed), float(params.wind.direction), float(params.wind.gust_stretch)
    key = f"{seed} {direction!r} {stretch!r}"
    if image.get(GUST_KEY) == key:
        return
    _write_grey(image, gusts.pattern(seed, direction, stretch))  # row 0 is y = 0, as Blender's pixel rows
    image[GUST_KEY] = key


PATCH_KEY = "wg_patches"  # custom property of the patch image: the settings it was painted from
PATCH_RANGE = 3.0  # the patch image's bytes hold tint / PATCH_RANGE (the material scales them back)
STAND_MAX = sward.STAND_RANGE[1]  # ... and its alpha the patches' stands L (sward.patch_stands) / STAND_MAX


def ensure_patch_image(name: str):
    """The packed byte image (Non-Color) of how the meadow's patches tint the far grass over the
    field (RGB: ``sward.patch_tint`` / PATCH_RANGE, a byte a channel, 1 % steps of the tint, a quarter
    of a float image's size in the saved file) and the stand the far canopy's edge draws there (alpha:
    ``sward.patch_stands`` / STAND_MAX); its size is ``paint_patch_image``'s."""
    return _grey_image(name, None, float_buffer=False, alpha=True)


def paint_patch_image(image, params: Params) -> None:
    """Write the patches' tint and stands of the field's settings (its field and blade sections:
    what decides the species mix and the lengths) into ``image`` unless it already holds them; one
    pixel without patches."""
    key = hashlib.sha1(json.dumps([edit_parts.digest_of(params, (edit_parts.LAYOUT, edit_parts.LOOK)),
                                   "stands"]).encode()).hexdigest()
    if image.get(PATCH_KEY) == key:
        return
    tint, stands = sward.patch_tint(params), sward.patch_stands(params)
    n = sward.PATCH_PIXELS if np.any(tint != 1.0) or np.any(stands != 1.0) else 1  # (a lawn's file stays small)
    if tuple(image.size) != (n, n):
        image.scale(n, n)
    _write_grey(image, np.clip(tint[:n, :n] / PATCH_RANGE, 0.0, 1.0), np.clip(stands[:n, :n] / STAND_MAX, 0.0, 1.0))
    image[PATCH_KEY] = key


def ensure_trail_image(name: str):
    """The float image the far canopy reads its trampled trails from (``interaction.trail_map``),
    written by ``write_trail_image`` on frames with trails."""
    return _grey_image(name, interaction.TRAIL_PIXELS)


def write_trail_image(image, flat: np.ndarray) -> None:
    """Write a trail map's flatness (rows from y0 up, as Blender's pixel rows) into ``image``."""
    _write_grey(image, flat)
