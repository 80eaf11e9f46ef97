"""The 500x500 trail layer ("path image") of turtlesim, its colour sensor and a PNG export.

The real node keeps trails on a separate ARGB image cleared to transparent *white*; the colour
sensor reads that layer, never the background, which is why an untouched canvas reads
(255, 255, 255).  We keep the same layer as a numpy array so the colour sensor matches, and
composite background + trails + simple turtle markers only when a PNG is written.

Rasterisation follows Qt's aliased wide-line rule as closely as a few lines allow: a segment is
the rectangle around it extended by half the pen width at both ends (square caps); pixel
(i, j) is painted when the point (i, j) lies inside (Qt draws aliased pixels to the right of
and below the mathematical point), with half-open bounds so a width-w line is w pixels wide.
No anti-aliasing.  PNG writing uses only zlib + struct (no PIL).
"""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

SIZE = 500
#: what QImage::pixel returns for coordinates outside the image (Qt 5), as r, g, b
_OUT_OF_RANGE = (0, 48, 57)
#: marker colours for turtles in the exported PNG (not part of the trail layer)
TURTLE_BODY = (46, 139, 87)
TURTLE_HEAD = (20, 80, 40)

# below this many pixels a plain Python loop beats numpy's per-call overhead
_SMALL_BOX = 144


class Canvas:
    """Trail layer: ``rgba`` is (500, 500, 4) uint8 indexed [row = screen y, column = x]."""

    def __init__(self, size: int = SIZE) -> None:
        self.size = size
        self.rgba = np.empty((size, size, 4), dtype=np.uint8)
        self.clear()

    def clear(self) -> None:
        """Fully transparent white, like ``path_image_.fill(qRgba(255, 255, 255, 0))``."""
        self.rgba[...] = (255, 255, 255, 0)

    def pixel(self, px: int, py: int) -> tuple[int, int, int]:
        """Colour sensor read of the trail layer at integer pixel (px, py)."""
        if 0 <= px < self.size and 0 <= py < self.size:
            r, g, b, _a = self.rgba[py, px].tolist()
            return (r, g, b)
        return _OUT_OF_RANGE

    def draw_line(self, x1: float, y1: float, x2: float, y2: float,
                  r: int, g: int, b: int, width: int) -> None:
        """Draw one solid, square-capped, aliased segment in pixel coordinates."""
        if not (math.isfinite(x1) and math.isfinite(y1) and math.isfinite(x2)
                and math.isfinite(y2)):
            return
        hw = max(int(width), 1) / 2.0
        dx = x2 - x1
        dy = y2 - y1
        length = math.hypot(dx, dy)
        if length > 0.0:
            ux = dx / length
            uy = dy / length
        else:
            ux, uy = 1.0, 0.0
        reach = hw * 1.5 + 1.0  # >= hw * sqrt(2): covers the rotated caps
        i0 = max(0, math.floor(min(x1, x2) - reach))
        i1 = min(self.size - 1, math.ceil(max(x1, x2) + reach))
        j0 = max(0, math.floor(min(y1, y2) - reach))
        j1 = min(self.size - 1, math.ceil(max(y1, y2) + reach))
        if i0 > i1 or j0 > j1:
            return
        lo = -hw
        hi = length + hw
        if (i1 - i0 + 1) * (j1 - j0 + 1) <= _SMALL_BOX:
            out = self.rgba
            color = (r, g, b, 255)
            for j in range(j0, j1 + 1):
                py = j - y1
                for i in range(i0, i1 + 1):
                    px = i - x1
                    a = px * ux + py * uy
                    p = py * ux - px * uy
                    if lo <= a < hi and lo <= p < hw:
                        out[j, i] = color
            return
        jj, ii = np.mgrid[j0:j1 + 1, i0:i1 + 1]
        px = ii - x1
        py = jj - y1
        a = px * ux + py * uy
        p = py * ux - px * uy
        mask = (a >= lo) & (a < hi) & (p >= lo) & (p < hw)
        self.rgba[j0:j1 + 1, i0:i1 + 1][mask] = (r, g, b, 255)

    def composite(self, background: Sequence[int],
                  turtles: Iterable[tuple[float, float, float]] = ()) -> np.ndarray:
        """RGB image as the window shows it: background, trails on top, turtle markers.

        ``turtles`` are (px, py, theta) in pixel coordinates / world heading.
        """
        rgb = np.empty((self.size, self.size, 3), dtype=np.uint8)
        rgb[...] = np.asarray(background, dtype=np.uint8)[:3]
        alpha = self.rgba[:, :, 3:4].astype(np.uint16)
        rgb[...] = ((self.rgba[:, :, :3].astype(np.uint16) * alpha
                     + rgb.astype(np.uint16) * (255 - alpha) + 127) // 255).astype(np.uint8)
        for px, py, theta in turtles:
            _disc(rgb, px, py, 9.0, TURTLE_BODY)
            _disc(rgb, px + 10.0 * math.cos(theta), py - 10.0 * math.sin(theta), 4.0, TURTLE_HEAD)
        return rgb

    def save_png(self, path: str | Path, background: Sequence[int],
                 turtles: Iterable[tuple[float, float, float]] = ()) -> Path:
        """Write the composited window image as an 8-bit RGB PNG; returns the path."""
        return write_png(path, self.composite(background, turtles))


def _disc(rgb: np.ndarray, cx: float, cy: float, radius: float, color: Sequence[int]) -> None:
    if not (math.isfinite(cx) and math.isfinite(cy)):
        return
    h, w = rgb.shape[:2]
    i0, i1 = max(0, math.floor(cx - radius)), min(w - 1, math.ceil(cx + radius))
    j0, j1 = max(0, math.floor(cy - radius)), min(h - 1, math.ceil(cy + radius))
    if i0 > i1 or j0 > j1:
        return
    jj, ii = np.mgrid[j0:j1 + 1, i0:i1 + 1]
    mask = (ii - cx) ** 2 + (jj - cy) ** 2 <= radius * radius
    rgb[j0:j1 + 1, i0:i1 + 1][mask] = color


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def encode_png(rgb: np.ndarray) -> bytes:
    """PNG bytes of an (h, w, 3) uint8 image: filter 0 on every row, zlib level 6."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError("expected an (h, w, 3) uint8 array")
    h, w = rgb.shape[:2]
    raw = np.zeros((h, 1 + 3 * w), dtype=np.uint8)
    raw[:, 1:] = rgb.reshape(h, 3 * w)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)
            + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + _chunk(b"IEND", b""))


def write_png(path: str | Path, rgb: np.ndarray) -> Path:
    """Write atomically (temp file + rename) so a reader never sees half a PNG."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(encode_png(rgb))
    tmp.replace(path)
    return path


def read_png(path: str | Path) -> np.ndarray:
    """Decode an 8-bit RGB/RGBA, non-interlaced PNG into an (h, w, 3|4) uint8 array.

    Handles all five row filters, so it also reads PNGs not written by :func:`encode_png`.
    """
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos = 8
    idat = b""
    width = height = channels = 0
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, ctype, _c, _f, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise ValueError(f"{path}: only 8-bit RGB/RGBA non-interlaced PNGs are supported")
            channels = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    stride = width * channels
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(height, 1 + stride)
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int32)
    for row in range(height):
        ftype = int(raw[row, 0])
        line = raw[row, 1:].astype(np.int32)
        if ftype == 0:
            cur = line
        elif ftype == 2:
            cur = (line + prev) & 0xFF
        else:  # Sub, Average, Paeth depend on the left neighbour: go byte by byte
            cur = np.zeros(stride, dtype=np.int32)
            for i in range(stride):
                left = int(cur[i - channels]) if i >= channels else 0
                up = int(prev[i])
                ul = int(prev[i - channels]) if i >= channels else 0
                if ftype == 1:
                    pred = left
                elif ftype == 3:
                    pred = (left + up) // 2
                elif ftype == 4:
                    p = left + up - ul
                    pa, pb, pc = abs(p - left), abs(p - up), abs(p - ul)
                    pred = left if pa <= pb and pa <= pc else (up if pb <= pc else ul)
                else:
                    raise ValueError(f"{path}: bad PNG filter type {ftype}")
                cur[i] = (int(line[i]) + pred) & 0xFF
        out[row] = cur
        prev = cur
    return out.reshape(height, width, channels)
