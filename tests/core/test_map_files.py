"""Map files that would hang, exhaust memory or crash with a traceback are refused with a sentence
naming the setting (images.py, schema paths, paint without Blender, the memory estimate)."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import tracemalloc
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from windgrass.grass_addon import images, memory, paint, schema
from windgrass.grass_addon.errors import ParameterError

REPO = Path(__file__).resolve().parents[2]


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)


def _png(width, height, idat: bytes, colour=0, depth=8, header: bytes | None = None) -> bytes:
    header = header if header is not None else struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    return images.SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


@contextmanager
def _at_once(seconds=10):
    """Fails the test instead of hanging when the call does not return within ``seconds``."""
    def stop(*_):
        raise TimeoutError(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _bomb(megabytes_out: int) -> bytes:
    """Deflate data of ``megabytes_out`` MB of zeros (about 1/1000 of that on disk), made from
    one compressed 64 MB block repeated (each ends on a full flush, so the copies join)."""
    block = bytes(64 << 20)
    deflate = zlib.compressobj(9)
    first = deflate.compress(block) + deflate.flush(zlib.Z_FULL_FLUSH)
    again = deflate.compress(block) + deflate.flush(zlib.Z_FULL_FLUSH)
    return first + again * (megabytes_out // 64 - 1)


def test_a_zlib_bomb_is_refused_without_inflating_it(tmp_path):
    """A 2 MB PNG whose header says 1 x 1 but whose data inflates to about 2 GB: refused, and the
    read takes less than 100 MB beside the file itself."""
    data = _png(1, 1, _bomb(2048))
    assert 1 << 20 < len(data) < 4 << 20
    path = tmp_path / "bomb.png"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        with pytest.raises(ParameterError, match="paint.density") as info:
            images.read_map(path, "paint.density")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert "more image data than its header" in str(info.value)
    assert peak < len(data) + (100 << 20), peak


@pytest.mark.parametrize("make", ["device", "fifo", "folder"])
def test_what_is_not_a_file_is_refused_at_once(tmp_path, make):
    if make == "device":
        path = Path("/dev/zero")
    elif make == "fifo":
        path = tmp_path / "pipe.png"
        os.mkfifo(path)
    else:
        path = tmp_path / "maps.png"
        path.mkdir()
    with _at_once(), pytest.raises(ParameterError, match="paint.density") as info:
        images.read_map(path, "paint.density")
    assert ("folder" if make == "folder" else "not a regular file") in str(info.value)


def test_a_header_of_the_wrong_size_is_a_sentence(tmp_path):
    path = tmp_path / "short.png"
    path.write_bytes(_png(1, 1, zlib.compress(b"\0\0"), header=b"\0\0\0\1\0\0\0\1\x08\0\0\0"))
    for name in ("paint.density", "terrain.heightmap"):
        with pytest.raises(ParameterError, match=name) as info:
            images.read_map(path, name)
        assert "image header of 12 bytes" in str(info.value)


def test_a_valid_map_still_reads(tmp_path):
    """The bounded inflation reads what it always read: an 8-bit grey map, each row filter."""
    path = tmp_path / "ramp.png"
    values = np.linspace(0.0, 1.0, 48).reshape(6, 8)
    path.write_bytes(images.encode_png(values))
    np.testing.assert_allclose(images.read_map(path, "paint.density"), values, atol=0.5 / 255)


def _scene(text: str, folder: Path):
    return schema.loads_toml(text, source="scene.toml", folder=folder)


@pytest.mark.parametrize("value, words", [
    ("map\\u0000.png", "NUL character"),
    ("~nosuchuser_windgrass/x.png", "nosuchuser_windgrass"),
])
def test_a_scene_files_unusable_path_is_named(tmp_path, value, words):
    with pytest.raises(ParameterError) as info:
        _scene(f'[paint]\ndensity = "{value}"\n', tmp_path)
    assert info.value.key == "paint.density" and words in str(info.value)


def test_a_null_byte_in_a_map_path_is_a_sentence():
    with pytest.raises(ParameterError, match="NUL character"):
        images.read_map("map\x00.png", "paint.length")


def test_a_blender_source_stays_a_source_in_a_scene_file_and_is_refused_without_blender(tmp_path):
    """``vertex_group:paths`` in a scene file is not made a path; read without Blender it is
    refused, saying it needs Blender's terrain and suggesting a PNG."""
    params = _scene('[paint]\ndensity = "vertex_group:paths"\n', tmp_path)
    assert params.paint.density == "vertex_group:paths"
    with pytest.raises(ParameterError) as info:
        paint.from_params(params, images.read_map)
    assert info.value.key == "paint.density" and "PNG" in str(info.value) and "Blender" in str(info.value)


@pytest.mark.slow  # (each starts Python again: dev.py test --quick leaves them out)
@pytest.mark.parametrize("flag", ["--paint-density", "--paint-length"])
@pytest.mark.parametrize("source", ["vertex_group:paths", "image:mask", "attribute:mown"])
def test_simulate_refuses_a_blender_only_source(flag, source):
    proc = subprocess.run([sys.executable, str(REPO / "headless" / "simulate.py"), "--field-blocks-x", "1",
                           "--field-blocks-y", "1", "--frames", "1", flag, source],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert flag[2:].replace("-", ".", 1) in proc.stderr and "PNG" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_the_largest_map_counts_in_the_memory_estimate(tmp_path):
    """A header of an 8192 x 8192 16-bit RGBA map (the largest a map may be) adds gigabytes to
    the estimate; where the field fits and the map does not, the map's setting is named."""
    path = tmp_path / "huge.png"
    path.write_bytes(_png(8192, 8192, b"", colour=6, depth=16))
    plain = schema.defaults()
    painted = plain.replace({"paint.density": str(path)})
    extra = memory.estimate(painted).total - memory.estimate(plain).total
    assert extra > 8192 * 8192 * 4 * 4  # at least its float32 RGBA values
    fits = (memory.estimate(plain).total >> 20) + 200
    with pytest.raises(ParameterError) as info:
        memory.check(painted.replace({"simulation.memory_mb": fits}))
    assert info.value.key == "paint.density" and "fewer pixels" in str(info.value)
    memory.check(plain.replace({"simulation.memory_mb": fits}))  # the field alone fits


@pytest.mark.parametrize("palette", [b"", b"\x10\x20", bytes(771)])
def test_a_palette_image_with_an_empty_or_broken_palette_is_a_sentence(tmp_path, palette):
    """Issue #57: a palette PNG whose palette is empty (or not whole colours, or over 256) was an
    IndexError (numpy 1.26) or OverflowError (numpy 2) from the map reader."""
    header = struct.pack(">IIBBBBB", 2, 2, 8, 3, 0, 0, 0)
    data = (images.SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"PLTE", palette)
            + _chunk(b"IDAT", zlib.compress(b"\0\0\1\0\1\0")) + _chunk(b"IEND", b""))
    path = tmp_path / "palette.png"
    path.write_bytes(data)
    with pytest.raises(ParameterError, match="paint.density") as info:
        images.read_map(path, "paint.density")
    assert f"a palette of {len(palette)} bytes" in str(info.value) and "1 to 256 colours" in str(info.value)


def test_a_palette_image_with_its_palette_still_reads(tmp_path):
    header = struct.pack(">IIBBBBB", 2, 1, 8, 3, 0, 0, 0)
    data = (images.SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"PLTE", b"\0\0\0\xff\xff\xff")
            + _chunk(b"IDAT", zlib.compress(b"\0\0\1")) + _chunk(b"IEND", b""))
    path = tmp_path / "palette.png"
    path.write_bytes(data)
    np.testing.assert_allclose(images.read_map(path, "paint.density"), [[0.0, 1.0]])


# Scene files that took minutes or gigabytes (issue #57): a dotted key of quoted parts with spaces
# slipped past the depth check into Python's TOML parser (44 s, growing as the square of the
# parts); the check's own pattern backtracked over a long comment or string (minutes).
HOSTILE_TOML = {
    "quoted parts": "[field]\n" + ".".join(['"a b"'] * 40_000) + " = 1\n",
    "spaced parts": "[field]\n" + " . ".join(["'a.b'"] * 40_000) + " = 1\n",
    "a table's name": "[" + ".".join(["a"] * 40_000) + "]\n",
    "an inline table's key": "[field]\nx = {" + ".".join(["a"] * 40_000) + " = 1}\n",
    "a long comment": "#" + "x" * 3_900_000 + "\n",
    "a long string": "[camera]\nmode = \"" + "x" * 3_000_000 + "\"\n",
}


@pytest.mark.slow  # (each case a few seconds under tracemalloc)
@pytest.mark.parametrize("case", list(HOSTILE_TOML))
def test_a_hostile_scene_file_is_answered_within_a_second_and_100_mb(case):
    text = HOSTILE_TOML[case]
    tracemalloc.start()
    try:
        with _at_once(10):
            try:
                schema.loads_toml(text)
                message = ""  # (a comment of any length is a valid scene file: the defaults)
            except ParameterError as exc:
                message = str(exc)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert bool(message) == (case != "a long comment"), message
    if "key" in case or "parts" in case or "name" in case:
        assert "40000 dotted parts" in message and f"at most {schema.MAX_KEY_DEPTH}" in message, message
    assert len(message) < 400, len(message)  # (the 3 MB value is named, not printed)
    assert peak < len(text) * 4 + (100 << 20), peak


def test_the_key_depth_guard_counts_only_keys():
    """What a real scene file holds reads as shallow: floats, dotted words inside strings and
    comments, a date, paths."""
    text = ('# a comment with a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r\n[wind]\nspeed = 5.5\n'
            'path = "x.y.z.w.v.u.t.s.r.q.p.o.n.m.l.k.j.i"\nkeys = [{time = 1.5, speed = 2.25}]\n'
            "when = 1979-05-27T07:32:00.999\n[paint]\ndensity = 'maps/a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.png'\n")
    assert schema._deepest_key(text) == 2
    assert schema._deepest_key("[a.b.c]\n") == 3 and schema._deepest_key('"a b" . c . d = 1') == 3
