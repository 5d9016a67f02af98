"""Draws the environment image of scenes/environment.json: a procedural sky as a small OpenEXR file.

Pure Python 3 (standard library only). The image is equirectangular, 256x128, as the renderer maps it
(docs/environment-lighting.md): rows from the zenith down to the nadir, the centre column looking along -z and
columns growing towards +x. A blue sky brightening towards the horizon, a grey-brown ground, and a sun about
2000 times brighter than the sky, 35 degrees up and 40 degrees to the right of -z, so that it casts sharp shadows.
The file is written by a small OpenEXR encoder: half-float R, G, B, one scanline per block, zlib-compressed
(ZIPS), as the OpenEXR library writes it.

Usage: python3 tools/scenes/make_environment.py [output.exr]   (default: scenes/textures/sky-256x128.exr)
"""

import math
import struct
import sys
import zlib
from pathlib import Path

WIDTH, HEIGHT = 256, 128
SUN_ELEVATION, SUN_AZIMUTH = math.radians(35), math.radians(40)  # azimuth from -z towards +x
SUN_RADIUS = math.radians(2.0)  # wider than the real sun (0.27 degrees) so that it covers a few texels
SUN_RADIANCE = (2400.0, 2100.0, 1700.0)


def direction(u, v):
    """The unit direction of the image's (u, v), as the renderer maps it."""
    azimuth, theta = 2 * math.pi * (u - 0.5), math.pi * v
    return (math.sin(theta) * math.sin(azimuth), math.cos(theta), -math.sin(theta) * math.cos(azimuth))


def radiance(d):
    sun = (math.cos(SUN_ELEVATION) * math.sin(SUN_AZIMUTH), math.sin(SUN_ELEVATION), -math.cos(SUN_ELEVATION) * math.cos(SUN_AZIMUTH))
    if sum(a * b for a, b in zip(d, sun)) > math.cos(SUN_RADIUS):
        return SUN_RADIANCE
    y = d[1]
    if y < 0:  # the ground: darker straight down
        shade = 0.35 + 0.15 * math.exp(8 * y)
        return (shade * 0.55, shade * 0.48, shade * 0.40)
    # The sky: deep blue above, pale near the horizon, a glow around the sun.
    horizon = math.exp(-6 * y)
    glow = max(0.0, sum(a * b for a, b in zip(d, sun))) ** 32
    return (0.25 + 0.75 * horizon + 2.0 * glow, 0.45 + 0.6 * horizon + 1.6 * glow, 1.0 + 0.3 * horizon + 1.0 * glow)


def texel(column, row, samples=4):
    """The texel's mean radiance over a samples x samples grid, so that the sun's edge is anti-aliased."""
    total = [0.0, 0.0, 0.0]
    for i in range(samples):
        for j in range(samples):
            value = radiance(direction((column + (i + 0.5) / samples) / WIDTH, (row + (j + 0.5) / samples) / HEIGHT))
            total = [t + c for t, c in zip(total, value)]
    return [t / samples**2 for t in total]


# ----------------------------------------------------------------------------------------------------------
# OpenEXR encoder (scanline image, half-float channels, ZIPS compression)
# ----------------------------------------------------------------------------------------------------------


def _attribute(name, kind, value):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def _zip_block(raw):
    """OpenEXR's zip compression: bytes split into even and odd halves, differences of neighbours, then zlib.
    A block that does not shrink is stored as it is (readers tell by its size)."""
    reordered = raw[0::2] + raw[1::2]
    predicted = bytearray(reordered)
    for i in range(1, len(reordered)):
        predicted[i] = (reordered[i] - reordered[i - 1] + 128) & 0xFF
    packed = zlib.compress(bytes(predicted), 9)
    return packed if len(packed) < len(raw) else raw


def encode_exr(width, height, pixels):
    """`pixels`: rows from the top, each a list of (r, g, b)."""
    channels = b"".join(name + b"\0" + struct.pack("<iB3xii", 1, 0, 1, 1) for name in (b"B", b"G", b"R")) + b"\0"  # 1: HALF
    window = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
              + _attribute("channels", "chlist", channels)
              + _attribute("compression", "compression", b"\x02")  # ZIPS: one scanline per block
              + _attribute("dataWindow", "box2i", window)
              + _attribute("displayWindow", "box2i", window)
              + _attribute("lineOrder", "lineOrder", b"\x00")
              + _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    blocks = []
    for y, row in enumerate(pixels):
        # A scanline holds each channel's values in turn, in the channels' (alphabetical) order.
        raw = b"".join(struct.pack("<%de" % width, *(p[c] for p in row)) for c in (2, 1, 0))
        data = _zip_block(raw)
        blocks.append(struct.pack("<ii", y, len(data)) + data)
    offset = len(header) + 8 * height
    table = b""
    for block in blocks:
        table += struct.pack("<Q", offset)
        offset += len(block)
    return header + table + b"".join(blocks)


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "scenes" / "textures" / "sky-256x128.exr"
    pixels = [[texel(column, row) for column in range(WIDTH)] for row in range(HEIGHT)]
    out.write_bytes(encode_exr(WIDTH, HEIGHT, pixels))
    print(f"{out}: {WIDTH}x{HEIGHT}, {out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
