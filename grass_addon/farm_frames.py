"""A farm job's frames on disk: whole, this job's, and stamped on the pixels they hold.

Standard library only: ``render_field.py`` reads it as part of the package, and a .blend's job
bundle carries a copy beside ``farm_render.py`` (which runs where the extension may be missing).

A rerun with ``--resume`` keeps a frame only when the file is a regular file (not a link, a pipe
or a device: reading one would wait forever or never end) of at most the bytes a frame of that
size can have, a PNG whose every chunk's CRC holds, whose image data inflates to exactly what its
header promises, and whose ``FRAME_KEY`` text is ``stamp(fingerprint, pixels)``: the job's
fingerprint (``farm.frame_fingerprint``: the frame's number, the settings, the input files,
Blender's and Windgrass's versions) hashed with the decoded image it was written on. So another
job's pixels under this job's text, a sparse file of gigabytes with a PNG's first and last bytes,
or a frame cut short are rendered again (issue #57).
"""

from __future__ import annotations

import hashlib
import os
import stat
import struct
import zlib
from pathlib import Path

FRAME_KEY = "WindgrassFrame"  # the PNG text chunk that says which job's frame a file is
SIGNATURE = b"\x89PNG\r\n\x1a\n"
CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}  # colour type -> samples per pixel
MAX_FRAME_BYTES = 1 << 30  # no frame of any size Blender renders to PNG is larger


class FrameError(Exception):
    """What lies under a frame's name is not a file a frame can be (a link, a pipe, a device)."""


def frame_bytes(width: int, height: int) -> int:
    """The most bytes a PNG of ``width`` x ``height`` can take: its rows stored raw at 16-bit RGBA
    (deflate's stored blocks add 5 bytes in 65,535) and a megabyte of chunks beside them."""
    raw = height * (width * 8 + 1)
    return min(MAX_FRAME_BYTES, raw + raw // 8192 + (1 << 20))


def read(path: Path, limit: int = MAX_FRAME_BYTES) -> bytes | None:
    """The bytes of the frame at ``path``; None when there is none or it is larger than ``limit``
    (not a whole frame: it is rendered again); FrameError when the name holds something that is not
    a regular file, which is never opened for reading."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(info.st_mode):
        raise FrameError(f"{path} is a link, not a frame: remove it (a frame is written as a file of its own)")
    if not stat.S_ISREG(info.st_mode):
        raise FrameError(f"{path} is not a regular file (a folder, a pipe or a device) where a frame goes: move it "
                         "away")
    if info.st_size > limit:
        return None
    fd = os.open(str(path), os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):  # (swapped for another since the look)
            raise FrameError(f"{path} is not a regular file where a frame goes: move it away")
        return fh.read(limit + 1)


def _chunks(data: bytes):
    """(kind, body) of each chunk up to IEND; ValueError when a chunk is cut, its CRC wrong, or
    IEND is missing."""
    if data[:8] != SIGNATURE:
        raise ValueError("no PNG signature")
    pos = 8
    while pos + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        end = pos + 12 + length
        if end > len(data):
            raise ValueError("a chunk cut short")
        if struct.unpack(">I", data[end - 4:end])[0] != zlib.crc32(data[pos + 4:end - 4]) & 0xFFFFFFFF:
            raise ValueError(f"chunk {kind!r} damaged (its CRC)")
        yield kind, data[pos + 8:end - 4]
        if kind == b"IEND":
            return
        pos = end
    raise ValueError("no IEND: the file is cut short")


def pixels_digest(data: bytes) -> tuple[str, int, int]:
    """(a hash of the decoded image, width, height) of a whole PNG; ValueError otherwise. The image
    data is inflated no further than its header's size (a zip bomb's gigabytes are never made)."""
    header, inflater, out, size = None, zlib.decompressobj(), bytearray(), 0
    for kind, body in _chunks(data):
        if kind == b"IHDR":
            if len(body) != 13:
                raise ValueError("an image header of the wrong size")
            header = body
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            if colour not in CHANNELS or depth not in (1, 2, 4, 8, 16):
                raise ValueError(f"colour type {colour}, {depth}-bit")
            size = height * ((width * CHANNELS[colour] * depth + 7) // 8 + 1)
        elif kind == b"IDAT":
            if header is None:
                raise ValueError("image data before its header")
            try:
                out += inflater.decompress(body, size - len(out) + 1)
            except zlib.error as exc:
                raise ValueError(f"damaged image data ({exc})") from None
            if len(out) > size:
                raise ValueError("more image data than its header's size")
    if header is None or len(out) != size:
        raise ValueError("the image data is missing or cut short")
    width, height = struct.unpack(">II", header[:8])
    return hashlib.sha256(header + bytes(out)).hexdigest(), width, height


def stamp(fingerprint: str, digest: str) -> str:
    """The text a frame of this job carries: its fingerprint bound to its pixels."""
    return hashlib.sha256(f"{fingerprint}:{digest}".encode()).hexdigest()[:32]


def texts(data: bytes) -> dict[str, str]:
    """The PNG's tEXt chunks {keyword: text} (latin-1, as the format says)."""
    out = {}
    for kind, body in _chunks(data):
        if kind == b"tEXt":
            key, _, text = body.partition(b"\0")
            out[key.decode("latin-1")] = text.decode("latin-1")
    return out


def stamped(data: bytes, fingerprint: str) -> bytes:
    """The PNG (text chunks dropped: Cycles' render times differ run to run) with its FRAME_KEY
    text, ``stamp(fingerprint, its pixels)``, before its IEND; ValueError when it is not whole."""
    digest, _, _ = pixels_digest(data)
    body = b"tEXt" + FRAME_KEY.encode() + b"\0" + stamp(fingerprint, digest).encode()
    parts = [SIGNATURE]
    for kind, chunk in _chunks(data):
        if kind == b"IEND":
            parts.append(struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF))
        if kind not in (b"tEXt", b"zTXt", b"iTXt"):
            parts.append(struct.pack(">I", len(chunk)) + kind + chunk
                         + struct.pack(">I", zlib.crc32(kind + chunk) & 0xFFFFFFFF))
    return b"".join(parts)


def kept(path: Path, fingerprint: str, size: tuple[int, int] | None = None) -> bool:
    """Whether the frame at ``path`` is whole, of ``size`` (width, height) when given, and this
    job's on these pixels; FrameError (from ``read``) when the name holds no regular file."""
    data = read(path, frame_bytes(*size) if size is not None else MAX_FRAME_BYTES)
    if data is None:
        return False
    try:
        digest, width, height = pixels_digest(data)
        text = texts(data).get(FRAME_KEY)
    except ValueError:
        return False
    return (size is None or (width, height) == tuple(size)) and text == stamp(fingerprint, digest)
