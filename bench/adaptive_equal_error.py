#!/usr/bin/env python3
"""Adaptive sampling against uniform sampling, to equal error: renders a scene uniformly and with --noise-threshold,
measures each image's error against a high-sample reference, and prints how much faster each is to the same error
(error squared times render time, the method of BENCHMARKS.md): for the linear values, for the values as displayed,
and for the noisiest 1 % of the picture as displayed. Only the program and the standard library are used,
so it runs on machines without NumPy.

The reference is two renders of R samples with different seeds, and an image's squared error is the product of its
differences from the two: for independent references that product's expectation is the image's own squared error,
without the references' noise (which, with one reference, is in every error measured and flatters the render with
more error).

  bench/adaptive_equal_error.py PATHTRACER SCENE --size 128x128 --reference-spp 8192 --uniform-spp 64 \\
      --adaptive 0.02:256 --adaptive 0.05:256 [--runs 3] [--references FOLDER] [-- EXTRA PROGRAM OPTIONS]
"""

import argparse
import array
import math
import re
import statistics
import subprocess
import sys
from pathlib import Path


def read_pfm(path):
    data = Path(path).read_bytes()
    header, rest = data.split(b"\n", 3)[:3], data.split(b"\n", 3)[3]
    width, height = map(int, header[1].split())
    values = array.array("f")
    values.frombytes(rest[: width * height * 12])
    if float(header[2]) > 0 and sys.byteorder == "little":
        values.byteswap()
    return width, height, values


def render(program, scene, size, spp, out, extra, threshold=None, seed=None):
    width, height = size
    command = [program, "render", str(scene), "--width", str(width), "--height", str(height), "--spp", str(spp), "-o", str(out)]
    if threshold is not None:
        command += ["--noise-threshold", str(threshold)]
    if seed is not None:
        command += ["--seed", str(seed)]
    run = subprocess.run(command + extra, capture_output=True, text=True, check=True)
    match = re.search(r"wrote .*?: ([0-9.]+) s, ([0-9.]+) ([kMG]?)samples/s", run.stderr)
    if not match:
        raise SystemExit(f"no closing line in: {run.stderr}")
    seconds = float(match.group(1))
    rate = float(match.group(2)) * {"": 1, "k": 1e3, "M": 1e6, "G": 1e9}[match.group(3)]
    return seconds, rate * seconds / (width * height)


def srgb(v):
    v = min(max(v, 0.0), 1.0)
    return 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055


def errors(image, references, width, height, block=8):
    """RMSE of the linear values; RMSE of the displayed ones (sRGB, clamped, as a PNG holds them); and the noisiest
    1 % of the picture: the 99th percentile of the displayed RMSE of its 8x8-pixel blocks. Squared differences are
    products of the differences from two independent references."""
    squared = displayed = 0.0
    blocks = {}
    for i, (a, r, q) in enumerate(zip(image, *references)):
        squared += (a - r) * (a - q)
        sa = srgb(a)
        d = (sa - srgb(r)) * (sa - srgb(q))
        displayed += d
        pixel = i // 3
        key = (pixel % width // block, pixel // width // block)
        blocks[key] = blocks.get(key, 0.0) + d
    n = len(image)
    root = lambda v: math.sqrt(max(v, 0.0))
    per_block = sorted(root(v / (3 * block * block)) for v in blocks.values())
    return root(squared / n), root(displayed / n), per_block[min(len(per_block) - 1, int(0.99 * len(per_block)))]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("program")
    parser.add_argument("scene")
    parser.add_argument("--size", default="128x128")
    parser.add_argument("--reference-spp", type=int, default=8192)
    parser.add_argument("--uniform-spp", type=int, default=64)
    parser.add_argument("--adaptive", action="append", default=[], help="THRESHOLD:MAX_SPP")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--references", default="/tmp/adaptive-references")
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    args = parser.parse_args(argv[: argv.index("--")] if "--" in argv else argv)
    args.extra = extra
    size = tuple(int(v) for v in args.size.split("x"))
    folder = Path(args.references)
    folder.mkdir(parents=True, exist_ok=True)
    references = []
    for seed in (987654, 987655):
        reference_path = folder / f"{Path(args.scene).stem}-{args.size}-{args.reference_spp}-{seed}.pfm"
        if not reference_path.exists():
            seconds, _ = render(args.program, args.scene, size, args.reference_spp, reference_path, args.extra, seed=seed)
            print(f"reference: {args.reference_spp} spp in {seconds:.1f} s")
        references.append(read_pfm(reference_path)[2])

    def measure(name, spp, threshold):
        times, samples = [], 0.0
        for _ in range(args.runs):
            seconds, samples = render(args.program, args.scene, size, spp, folder / "run.pfm", args.extra, threshold)
            times.append(seconds)
        rmse, displayed, worst = errors(read_pfm(folder / "run.pfm")[2], references, *size)
        return dict(name=name, seconds=statistics.median(times), spp=samples, rmse=rmse, displayed=displayed, worst=worst)

    rows = [measure(f"uniform {args.uniform_spp} spp", args.uniform_spp, None)]
    for entry in args.adaptive:
        threshold, most = entry.split(":")
        rows.append(measure(f"adaptive {threshold}, at most {most} spp", int(most), float(threshold)))
    base = rows[0]
    print(f"{Path(args.scene).name} {args.size} {' '.join(args.extra)} (median of {args.runs}; references 2 x {args.reference_spp} spp)")
    print("| sampling | time (s) | mean spp | RMSE linear | RMSE displayed | noisiest 1 % displayed | faster to equal: linear | displayed | noisiest 1 % |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        faster = [(base[k] ** 2 * base["seconds"]) / (row[k] ** 2 * row["seconds"]) for k in ("rmse", "displayed", "worst")]
        print(f"| {row['name']} | {row['seconds']:.3f} | {row['spp']:.1f} | {row['rmse']:.5f} | {row['displayed']:.5f} | {row['worst']:.5f} | "
              + " | ".join(f"{f:.2f}x" for f in faster) + " |")


if __name__ == "__main__":
    main()
