#!/usr/bin/env python3
"""Writes the texture fuzz target's seed corpus: one small valid file for each format stb_image reads (PNG in
several colour types, baseline JPEG, BMP, TGA, GIF, PPM/PGM, Radiance HDR, PSD), from a 16x8 reduction of
scenes/textures/planet-1024x512.png. Usage: fuzz/make_texture_seeds.py PPM_OF_THE_PLANET OUTPUT_FOLDER, where the
PPM is the texture decoded by any tool (e.g. `convert planet-1024x512.png ppm:-`)."""
import math
import struct
import sys
import zlib
from pathlib import Path

W, H = 16, 8


def read_ppm(path):
    data = Path(path).read_bytes()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    assert fields[0] == b"P6" and fields[3] == b"255"
    width, height = int(fields[1]), int(fields[2])
    return width, height, data[pos + 1:pos + 1 + 3 * width * height]


def reduce(width, height, rgb):
    out = []
    for y in range(H):
        for x in range(W):
            acc, n = [0, 0, 0], 0
            for yy in range(y * height // H, (y + 1) * height // H, 4):
                for xx in range(x * width // W, (x + 1) * width // W, 4):
                    i = 3 * (yy * width + xx)
                    for c in range(3):
                        acc[c] += rgb[i + c]
                    n += 1
            out.append(tuple(a // n for a in acc))
    return out  # W*H (r, g, b)


def png(pixels, color_type, bit_depth=8, palette=None):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    rows = b""
    for y in range(H):
        row = bytearray([y % 5])  # every filter type, raw data being the same for each
        raw = bytearray()
        for x in range(W):
            r, g, b = pixels[y * W + x]
            grey = (r * 299 + g * 587 + b * 114) // 1000
            if color_type == 2:
                raw += bytes([r, g, b]) if bit_depth == 8 else struct.pack(">HHH", r * 257, g * 257, b * 257)
            elif color_type == 6:
                raw += bytes([r, g, b, 255 - x * 8])
            elif color_type == 0:
                raw += bytes([grey])
            elif color_type == 4:
                raw += bytes([grey, 128 + y * 16])
            elif color_type == 3:
                raw += bytes([palette.index(pixels[y * W + x])])
        bpp = max(1, len(raw) // W)
        prior = rows_raw[-1] if rows_raw else bytes(len(raw))
        filtered = bytearray()
        for i, v in enumerate(raw):
            a = raw[i - bpp] if i >= bpp else 0
            b = prior[i]
            c = prior[i - bpp] if i >= bpp else 0
            kind = row[0]
            if kind == 0:
                pred = 0
            elif kind == 1:
                pred = a
            elif kind == 2:
                pred = b
            elif kind == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            filtered.append((v - pred) & 255)
        rows_raw.append(bytes(raw))
        rows += bytes(row) + bytes(filtered)
    rows_raw.clear()
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, bit_depth, color_type, 0, 0, 0))
    if palette:
        out += chunk(b"PLTE", b"".join(bytes(p) for p in palette))
    return out + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b"")


rows_raw = []


def bmp(pixels):
    stride = (3 * W + 3) & ~3
    body = b""
    for y in reversed(range(H)):
        row = b"".join(bytes([b, g, r]) for r, g, b in pixels[y * W:(y + 1) * W])
        body += row + bytes(stride - len(row))
    header = struct.pack("<2sIHHI", b"BM", 54 + len(body), 0, 0, 54)
    info = struct.pack("<IiiHHIIiiII", 40, W, H, 1, 24, 0, len(body), 2835, 2835, 0, 0)
    return header + info + body


def tga(pixels, rle):
    header = struct.pack("<BBBHHBHHHHBB", 0, 0, 10 if rle else 2, 0, 0, 0, 0, 0, W, H, 24, 0x20)
    body = bytearray()
    for y in range(H):
        row = pixels[y * W:(y + 1) * W]
        if not rle:
            body += b"".join(bytes([b, g, r]) for r, g, b in row)
            continue
        x = 0
        while x < W:  # runs of equal pixels as run packets, the rest as raw packets of one
            n = 1
            while x + n < W and n < 128 and row[x + n] == row[x]:
                n += 1
            r, g, b = row[x]
            body += bytes([(0x80 | (n - 1)) if n > 1 else 0, b, g, r])
            x += n
    return header + bytes(body)


def pnm(pixels, grey):
    if grey:
        return b"P5\n%d %d\n255\n" % (W, H) + bytes((r * 299 + g * 587 + b * 114) // 1000 for r, g, b in pixels)
    return b"P6\n# planet\n%d %d\n255\n" % (W, H) + b"".join(bytes(p) for p in pixels)


def hdr(pixels):
    body = bytearray()
    for r, g, b in pixels:
        lin = [(c / 255.0) ** 2.2 for c in (r, g, b)]
        m = max(lin)
        if m < 1e-32:
            body += bytes(4)
            continue
        mant, exp = math.frexp(m)
        scale = mant * 256.0 / m
        body += bytes([int(v * scale) for v in lin] + [exp + 128])
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (H, W) + bytes(body)


def psd(pixels):
    header = b"8BPS" + struct.pack(">H6xHIIHH", 1, 3, H, W, 8, 3) + struct.pack(">III", 0, 0, 0)
    planes = b"".join(bytes(p[c] for p in pixels) for c in range(3))
    return header + struct.pack(">H", 0) + planes


def gif(pixels, palette):
    # LZW with a clear code before every symbol's code width could grow: all codes stay 9 bits.
    indices = [palette.index(p) for p in pixels]
    codes, clear, end = [], 256, 257
    for i, v in enumerate(indices):
        if i % 200 == 0:
            codes.append(clear)
        codes.append(v)
    codes.append(end)
    bits, nbits, data = 0, 0, bytearray()
    for c in codes:
        bits |= c << nbits
        nbits += 9
        while nbits >= 8:
            data.append(bits & 255)
            bits >>= 8
            nbits -= 8
    if nbits:
        data.append(bits & 255)
    blocks = b"".join(bytes([len(data[i:i + 255])]) + bytes(data[i:i + 255]) for i in range(0, len(data), 255))
    table = b"".join(bytes(p) for p in palette) + bytes(3 * (256 - len(palette)))
    return (b"GIF89a" + struct.pack("<HHBBB", W, H, 0xF7, 0, 0) + table +
            b"\x2c" + struct.pack("<HHHHB", 0, 0, W, H, 0) + b"\x08" + blocks + b"\x00\x3b")


# Baseline JPEG, 4:4:4, quality 100 tables (all ones), each 8x8 block coded by its DC term only, with the standard
# Huffman tables of ITU T.81 Annex K.
DC_LUM = ([0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0], list(range(12)))
DC_CHR = ([0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0], list(range(12)))
AC_EOB = ([0, 1] + [0] * 14, [0])  # a table holding only EOB


def huffman_codes(table):
    counts, symbols = table
    codes, code, k = {}, 0, 0
    for length in range(1, 17):
        for _ in range(counts[length - 1]):
            codes[symbols[k]] = (code, length)
            code += 1
            k += 1
        code <<= 1
    return codes


def jpeg(pixels):
    def segment(marker, body):
        return bytes([0xFF, marker]) + struct.pack(">H", len(body) + 2) + body
    ycc = []
    for r, g, b in pixels:
        ycc.append((0.299 * r + 0.587 * g + 0.114 * b,
                    128 - 0.168736 * r - 0.331264 * g + 0.5 * b,
                    128 + 0.5 * r - 0.418688 * g - 0.081312 * b))
    out = b"\xff\xd8" + segment(0xE0, b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00")
    out += segment(0xDB, b"\x00" + bytes([1] * 64))
    out += segment(0xC0, struct.pack(">BHHB", 8, H, W, 3) + b"\x01\x11\x00\x02\x11\x00\x03\x11\x00")
    for cls_id, table in ((0x00, DC_LUM), (0x01, DC_CHR), (0x10, AC_EOB)):
        out += segment(0xC4, bytes([cls_id]) + bytes(table[0]) + bytes(table[1]))
    out += segment(0xDA, b"\x03\x01\x00\x02\x10\x03\x10\x00\x3f\x00")
    dc_codes = [huffman_codes(DC_LUM), huffman_codes(DC_CHR), huffman_codes(DC_CHR)]
    eob = huffman_codes(AC_EOB)[0]
    bits = []

    def put(value, length):
        bits.extend((value >> (length - 1 - i)) & 1 for i in range(length))
    previous = [0, 0, 0]
    for bx in range(W // 8):
        for comp in range(3):
            mean = sum(ycc[y * W + bx * 8 + x][comp] for y in range(8) for x in range(8)) / 64
            dc = int(round((mean - 128) * 8))  # the DC coefficient of a flat block, quantized by 1
            diff, previous[comp] = dc - previous[comp], dc
            size = abs(diff).bit_length()
            put(*dc_codes[comp][size])
            if size:
                put(diff if diff > 0 else diff + (1 << size) - 1, size)
            put(*eob)
    bits.extend([1] * (-len(bits) % 8))
    scan = bytearray()
    for i in range(0, len(bits), 8):
        byte = int("".join(map(str, bits[i:i + 8])), 2)
        scan.append(byte)
        if byte == 0xFF:
            scan.append(0)
    return out + bytes(scan) + b"\xff\xd9"


def main():
    pixels = reduce(*read_ppm(sys.argv[1]))
    out = Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    # A palette of at most 256 colours for PNG type 3 and GIF: the pixels quantized to 3-3-2 bits.
    quantized = [(r & 0xE0, g & 0xE0, b & 0xC0) for r, g, b in pixels]
    palette = sorted(set(quantized))
    files = {
        "rgb.png": png(pixels, 2),
        "rgb16.png": png(pixels, 2, 16),
        "rgba.png": png(pixels, 6),
        "grey.png": png(pixels, 0),
        "grey-alpha.png": png(pixels, 4),
        "palette.png": png(quantized, 3, 8, palette),
        "dc-only.jpg": jpeg(pixels),
        "rgb.bmp": bmp(pixels),
        "raw.tga": tga(pixels, False),
        "rle.tga": tga(quantized, True),
        "palette.gif": gif(quantized, palette),
        "rgb.ppm": pnm(pixels, False),
        "grey.pgm": pnm(pixels, True),
        "rgbe.hdr": hdr(pixels),
        "rgb.psd": psd(pixels),
    }
    for name, data in files.items():
        (out / name).write_bytes(data)


if __name__ == "__main__":
    main()
