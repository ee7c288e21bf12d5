"""PNG files as arrays of values (numpy and zlib only): the maps and heightmaps of scene files.

Batch renders and the numpy-only scripts read the same files the same way, so a painted field is
the same bits in Blender and outside it. 8- and 16-bit greyscale, grey + alpha, RGB, RGBA and
palette images, not interlaced (what image editors write by default). A map's value is the
image's grey level 0..1 (colour images: the mean of R, G and B), row 0 at the image's bottom,
so the image lies over the field as it looks on screen with +Y up.
"""

from __future__ import annotations

import os
import stat
import struct
import zlib

import numpy as np

from .errors import ParameterError

SIGNATURE = b"\x89PNG\r\n\x1a\n"
CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}  # colour type -> samples per pixel
MAX_PIXELS = 1 << 26  # 8192 x 8192
# A PNG's file is at most its raw pixels (8 bytes a pixel: 16-bit RGBA, plus a filter byte a row)
# and a little: anything longer is not a map (a device, a log, a zip bomb's padding).
MAX_FILE_BYTES = MAX_PIXELS * 8 + (64 << 20)


def read_map(path, name: str) -> np.ndarray:
    """(height, width) float32 grey levels 0..1 of the PNG at ``path``, row 0 at the bottom;
    ParameterError naming the setting ``name`` when it is missing, unreadable or not a PNG."""
    data = read_file(path, name)
    try:
        rgba = decode_png(data)
    except ValueError as exc:
        raise ParameterError(name, f"{path} is not an image this can read: {exc} (valid: a PNG, 8- or 16-bit, "
                             "grey or colour, not interlaced)") from None
    colour = rgba[..., :3].mean(axis=-1) if rgba.shape[-1] >= 3 else rgba[..., 0]
    return np.ascontiguousarray(colour[::-1], dtype=np.float32)


def read_file(path, name: str) -> bytes:
    """The bytes of the map file at ``path``, read only when it is a regular file of at most
    MAX_FILE_BYTES: a folder, a device (``/dev/zero``), a pipe (which would wait forever) or a path
    with a NUL character is refused at once with a ParameterError naming the setting."""
    text = str(path)
    if "\x00" in text:
        raise ParameterError(name, f"{text!r} holds a NUL character (valid: the path of a PNG image file)")
    try:
        info = os.stat(text)
    except FileNotFoundError:
        raise ParameterError(name, f"{text} does not exist (valid: a PNG image file)") from None
    except OSError as exc:
        raise ParameterError(name, f"cannot read {text}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise ParameterError(name, f"{text} is a folder, not a PNG image file")
    if not stat.S_ISREG(info.st_mode):
        raise ParameterError(name, f"{text} is not a regular file (a device or a pipe); valid: a PNG image file")
    if info.st_size > MAX_FILE_BYTES:
        raise ParameterError(name, f"{text} has {info.st_size:,} bytes, more than any PNG map of at most "
                             f"{MAX_PIXELS:,} pixels (valid: a PNG image file)")
    try:
        with open(text, "rb") as fh:
            return fh.read(info.st_size + 1)  # (read(n) takes n bytes at once: no more than the file's)
    except OSError as exc:
        raise ParameterError(name, f"cannot read {text}: {exc.strerror or exc}") from None


def decoded_bytes(width: int, height: int, channels: int = 4) -> int:
    """Memory the decoding of a ``width`` x ``height`` PNG of ``channels`` takes at its peak: the
    raw rows, the unfiltered copy and the float32 values, and the float32 grey map kept."""
    raw = height * (width * channels * 2 + 1)
    return 2 * raw + width * height * channels * 4 + width * height * 4


def peek_size(path) -> tuple[int, int, int] | None:
    """(width, height, channels) from a PNG file's header, reading its first bytes only (None
    when the path is not a readable regular PNG file: reading it says why)."""
    try:
        if not stat.S_ISREG(os.stat(str(path)).st_mode):
            return None
        with open(str(path), "rb") as fh:
            head = fh.read(33)
    except (OSError, ValueError):
        return None
    if head[:8] != SIGNATURE or head[12:16] != b"IHDR" or len(head) < 29:
        return None
    width, height, _, colour = struct.unpack(">IIBB", head[16:26])
    return width, height, CHANNELS.get(colour, 4)


def decode_png(data: bytes) -> np.ndarray:
    """(height, width, channels) float32 0..1 of a PNG (ValueError on anything else)."""
    if data[:8] != SIGNATURE:
        raise ValueError("no PNG signature")
    pos, header, palette, idat = 8, None, None, []
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if len(body) != length:
            raise ValueError("the file is cut short")
        pos += 12 + length
        if kind == b"IHDR":
            if length != 13:
                raise ValueError(f"an image header of {length} bytes (a PNG's has 13)")
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"PLTE":
            if not 3 <= length <= 768 or length % 3:
                raise ValueError(f"a palette of {length} bytes (valid: 1 to 256 colours of 3 bytes)")
            palette = np.frombuffer(body, np.uint8).reshape(-1, 3)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    if header is None or not idat:
        raise ValueError("no image header or data")
    width, height, depth, colour, _, _, interlace = header
    if colour not in CHANNELS or depth not in (8, 16) or interlace != 0:
        raise ValueError(f"colour type {colour}, {depth}-bit, interlace {interlace}")
    if colour == 3 and palette is None:
        raise ValueError("a palette image without its palette")
    if colour == 3 and depth != 8:
        raise ValueError(f"a {depth}-bit palette image (valid: 8-bit palette images)")
    if width * height > MAX_PIXELS or width == 0 or height == 0:
        raise ValueError(f"{width} x {height} pixels")
    channels = CHANNELS[colour]
    step = channels * depth // 8  # bytes per pixel
    stride = width * step
    raw = _inflate(idat, height * (stride + 1))
    rows = _unfilter(raw.reshape(height, stride + 1), step)
    if depth == 16:
        samples = rows.reshape(height, width * channels, 2)
        values = (samples[..., 0].astype(np.float32) * 256.0 + samples[..., 1]) / 65535.0
    else:
        values = rows.astype(np.float32) / 255.0
    values = values.reshape(height, width, channels)
    if colour == 3 and palette is not None:  # (checked above: a palette image has one)
        index = rows.reshape(height, width)
        values = palette[np.minimum(index, len(palette) - 1)].astype(np.float32) / 255.0
    return values


def _inflate(chunks: list[bytes], size: int) -> np.ndarray:
    """The ``size`` bytes of image data the header promises, inflated no further (a zip bomb's
    gigabytes are never made): ValueError when there is less, or more."""
    inflater = zlib.decompressobj()
    out = bytearray()
    try:
        for chunk in chunks:  # at most one byte past the size: enough to tell there is more
            out += inflater.decompress(chunk, size - len(out) + 1)
            if len(out) > size:
                break
    except zlib.error as exc:
        raise ValueError(f"damaged image data ({exc})") from None
    if len(out) > size:
        raise ValueError("more image data than its header's size")
    if len(out) < size:
        raise ValueError("the image data is cut short")
    return np.frombuffer(bytes(out), np.uint8)


def _unfilter(filtered: np.ndarray, step: int) -> np.ndarray:
    """Undo the PNG row filters (None, Sub, Up, Average, Paeth), row by row: None, Sub and Up in
    numpy, Average and Paeth (each byte needs the one before) on Python bytes."""
    height, width = filtered.shape[0], filtered.shape[1] - 1
    out = np.zeros((height, width), np.uint8)
    prev = np.zeros(width, np.uint8)
    for y in range(height):
        kind, line = int(filtered[y, 0]), filtered[y, 1:]
        if kind == 0:
            row = line
        elif kind == 1:  # Sub: a running sum along each byte lane
            lanes = line.reshape(-1, step).astype(np.uint32) if width % step == 0 else None
            if lanes is None:
                raise ValueError("a row is not a whole number of pixels")
            row = (np.cumsum(lanes, axis=0) & 0xFF).astype(np.uint8).ravel()
        elif kind == 2:  # Up
            row = (line.astype(np.uint16) + prev).astype(np.uint8)
        elif kind in (3, 4):
            cur, up, res = line.tobytes(), prev.tobytes(), bytearray(width)
            for i in range(width):
                left = res[i - step] if i >= step else 0
                if kind == 3:
                    res[i] = (cur[i] + ((left + up[i]) >> 1)) & 0xFF
                else:
                    upleft = up[i - step] if i >= step else 0
                    p = left + up[i] - upleft
                    pa, pb, pc = abs(p - left), abs(p - up[i]), abs(p - upleft)
                    res[i] = (cur[i] + (left if pa <= pb and pa <= pc else up[i] if pb <= pc else upleft)) & 0xFF
            row = np.frombuffer(bytes(res), np.uint8)
        else:
            raise ValueError(f"unknown row filter {kind}")
        out[y] = row
        prev = out[y]
    return out


def encode_png(values: np.ndarray) -> bytes:
    """An 8-bit greyscale PNG (filter None) of values 0..1 (rows with row 0 at the bottom): what
    the tests and scripts write as maps."""
    grey = np.clip(np.round(np.asarray(values, np.float64)[::-1] * 255.0), 0, 255).astype(np.uint8)
    height, width = grey.shape
    raw = np.concatenate([np.zeros((height, 1), np.uint8), grey], axis=1).tobytes()

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return SIGNATURE + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
