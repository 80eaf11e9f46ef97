"""Trail rasterisation, colour-sensor reads and the dependency-free PNG writer/reader."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from grader.sim.canvas import Canvas, encode_png, read_png, write_png


def painted(canvas: Canvas) -> set[tuple[int, int]]:
    """(column, row) of every painted pixel."""
    rows, cols = (canvas.rgba[:, :, 3] > 0).nonzero()
    return {(int(c), int(r)) for r, c in zip(rows, cols)}


def test_new_canvas_is_transparent_white() -> None:
    canvas = Canvas()
    assert canvas.rgba.shape == (500, 500, 4)
    assert (canvas.rgba == np.array([255, 255, 255, 0], dtype=np.uint8)).all()
    assert canvas.pixel(250, 250) == (255, 255, 255)


def test_horizontal_segment_has_square_caps_and_exact_width() -> None:
    canvas = Canvas()
    canvas.draw_line(110.0, 100.0, 100.0, 100.0, 1, 2, 3, 3)
    # square caps extend half the width (1.5 px) past both ends; 3 rows for width 3
    assert painted(canvas) == {(i, j) for i in range(99, 112) for j in (99, 100, 101)}
    assert canvas.pixel(105, 100) == (1, 2, 3)


def test_vertical_and_diagonal_segments_cover_their_centre_line() -> None:
    canvas = Canvas()
    canvas.draw_line(50.0, 50.0, 50.0, 80.0, 9, 9, 9, 1)
    assert {i for i, _j in painted(canvas)} == {50}
    canvas.clear()
    canvas.draw_line(200.0, 200.0, 260.0, 260.0, 9, 9, 9, 3)
    pix = painted(canvas)
    assert all((k, k) in pix for k in range(199, 262))
    assert (200, 260) not in pix and (230, 236) not in pix   # no stray pixels off the line


def test_zero_length_segment_is_a_square_dot() -> None:
    canvas = Canvas()
    canvas.draw_line(20.0, 30.0, 20.0, 30.0, 5, 5, 5, 4)
    assert painted(canvas) == {(i, j) for i in range(18, 22) for j in range(28, 32)}


def test_small_and_large_rasterisers_agree() -> None:
    """Short segments use a Python loop, long ones numpy: both must paint the same pixels."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        x1, y1 = rng.uniform(5, 495, 2)
        angle = rng.uniform(0, 2 * np.pi)
        width = int(rng.integers(1, 6))
        length = rng.uniform(0.0, 3.0)
        x2, y2 = x1 + length * np.cos(angle), y1 + length * np.sin(angle)
        small = Canvas()
        small.draw_line(x1, y1, x2, y2, 1, 1, 1, width)
        big = Canvas()
        import grader.sim.canvas as mod
        saved = mod._SMALL_BOX
        mod._SMALL_BOX = -1
        try:
            big.draw_line(x1, y1, x2, y2, 1, 1, 1, width)
        finally:
            mod._SMALL_BOX = saved
        assert painted(small) == painted(big)


def test_segments_are_clipped_and_non_finite_ignored() -> None:
    canvas = Canvas()
    canvas.draw_line(-50.0, 10.0, 600.0, 10.0, 1, 1, 1, 3)
    assert {j for _i, j in painted(canvas)} == {9, 10, 11}
    canvas.clear()
    canvas.draw_line(float("nan"), 1.0, 2.0, 3.0, 1, 1, 1, 3)
    assert not painted(canvas)
    assert canvas.pixel(-1, 3) == (0, 48, 57)  # QImage::pixel out of range (Qt 5)


def test_composite_background_under_trail_and_turtle_marker() -> None:
    canvas = Canvas()
    canvas.draw_line(10.0, 10.0, 100.0, 10.0, 179, 184, 255, 3)
    rgb = canvas.composite((69, 86, 255), [(400.0, 400.0, 0.0)])
    assert tuple(rgb[10, 50]) == (179, 184, 255)
    assert tuple(rgb[300, 300]) == (69, 86, 255)
    assert tuple(rgb[400, 400]) != (69, 86, 255)  # the turtle marker


def test_png_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    out = write_png(tmp_path / "sub" / "x.png", img)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (read_png(out) == img).all()
    assert not (tmp_path / "sub" / "x.png.tmp").exists()


def test_png_chunks_have_valid_crc() -> None:
    data = encode_png(np.zeros((4, 5, 3), dtype=np.uint8))
    pos, kinds = 8, []
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF
        kinds.append(kind)
        pos += 12 + length
    assert kinds == [b"IHDR", b"IDAT", b"IEND"]
    assert struct.unpack(">IIBBBBB", data[16:29]) == (5, 4, 8, 2, 0, 0, 0)


def test_read_png_handles_all_filters(tmp_path: Path) -> None:
    """A PNG whose rows use Sub, Up, Average and Paeth filters decodes to the right pixels."""
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (5, 6, 3), dtype=np.int32)
    flat = img.reshape(5, 18)
    rows = []
    prev = np.zeros(18, dtype=np.int32)
    for r, ftype in enumerate([1, 2, 3, 4, 0]):
        cur = flat[r]
        left = np.concatenate([[0, 0, 0], cur[:-3]])
        ul = np.concatenate([[0, 0, 0], prev[:-3]])
        if ftype == 0:
            pred = np.zeros(18, dtype=np.int32)
        elif ftype == 1:
            pred = left
        elif ftype == 2:
            pred = prev
        elif ftype == 3:
            pred = (left + prev) // 2
        else:
            p = left + prev - ul
            pa, pb, pc = abs(p - left), abs(p - prev), abs(p - ul)
            pred = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, prev, ul))
        rows.append(bytes([ftype]) + bytes(((cur - pred) & 0xFF).astype(np.uint8)))
        prev = cur

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(
            ">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    path = tmp_path / "f.png"
    header = chunk(b"IHDR", struct.pack(">IIBBBBB", 6, 5, 8, 2, 0, 0, 0))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + header
                     + chunk(b"IDAT", zlib.compress(b"".join(rows))) + chunk(b"IEND", b""))
    assert (read_png(path) == img).all()


def test_read_png_rejects_non_png(tmp_path: Path) -> None:
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"GIF89a....")
    with pytest.raises(ValueError):
        read_png(bad)
