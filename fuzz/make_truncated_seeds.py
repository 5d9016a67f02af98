#!/usr/bin/env python3
"""Writes the texture fuzz target's corpus of truncated files: for one seed of each kind in corpus-texture_image
(a kind: the file's first three bytes, which tell the format and mostly its layout), copies cut just after the
header, at half its length and one byte short; and the Radiance file that made stb_image 2.27 loop for ever (a
header, then the first bytes of one run-length encoded scanline, then the end of the file; CVE-2021-42715).
Usage: fuzz/make_truncated_seeds.py SEED_FOLDER OUTPUT_FOLDER. Files are named by their SHA-1, as libFuzzer names
what it keeps."""
import hashlib
import sys
from pathlib import Path


def write(folder, data):
    (folder / hashlib.sha1(data).hexdigest()).write_bytes(data)


def main():
    seeds, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    kinds = {}
    for path in sorted(seeds.iterdir()):
        data = path.read_bytes()
        if len(data) >= 8:
            kinds.setdefault(data[:3], data)
    for data in kinds.values():
        for cut in sorted({min(40, len(data) - 1), len(data) // 2, len(data) - 1}):
            write(out, data[:cut])
    header = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 64\n"
    write(out, header + bytes([2, 2, 0, 64]))
    write(out, header)


if __name__ == "__main__":
    main()
