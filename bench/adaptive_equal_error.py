#!/usr/bin/env python3
"""Adaptive sampling against uniform sampling, to equal error: renders a scene uniformly and with --noise-threshold,
measures each image's error against a high-sample reference, and prints how much faster each is to the same error
(error squared times render time, the method of BENCHMARKS.md). Only the program and the standard library are used,
so it runs on machines without NumPy.

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


def errors(image, reference):
    """RMSE over every value, and the relative mean squared error (squared difference over reference squared plus 0.01)."""
    squared = relative = 0.0
    for a, r in zip(image, reference):
        d = (a - r) * (a - r)
        squared += d
        relative += d / (r * r + 0.01)
    n = len(reference)
    return math.sqrt(squared / n), relative / n


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
    reference_path = folder / f"{Path(args.scene).stem}-{args.size}-{args.reference_spp}.pfm"
    if not reference_path.exists():
        seconds, _ = render(args.program, args.scene, size, args.reference_spp, reference_path, args.extra, seed=987654)
        print(f"reference: {args.reference_spp} spp in {seconds:.1f} s")
    reference = read_pfm(reference_path)[2]

    def measure(name, spp, threshold):
        times, samples = [], 0.0
        for _ in range(args.runs):
            seconds, samples = render(args.program, args.scene, size, spp, folder / "run.pfm", args.extra, threshold)
            times.append(seconds)
        rmse, relmse = errors(read_pfm(folder / "run.pfm")[2], reference)
        return dict(name=name, seconds=statistics.median(times), spp=samples, rmse=rmse, relmse=relmse)

    rows = [measure(f"uniform {args.uniform_spp} spp", args.uniform_spp, None)]
    for entry in args.adaptive:
        threshold, most = entry.split(":")
        rows.append(measure(f"adaptive {threshold}, at most {most} spp", int(most), float(threshold)))
    base = rows[0]
    print(f"{Path(args.scene).name} {args.size} {' '.join(args.extra)} (median of {args.runs}; reference {args.reference_spp} spp)")
    print("| sampling | time (s) | mean spp | RMSE | relMSE | faster to equal RMSE | faster to equal relMSE |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        by_rmse = (base["rmse"] ** 2 * base["seconds"]) / (row["rmse"] ** 2 * row["seconds"])
        by_rel = (base["relmse"] * base["seconds"]) / (row["relmse"] * row["seconds"])
        print(f"| {row['name']} | {row['seconds']:.3f} | {row['spp']:.1f} | {row['rmse']:.5f} | {row['relmse']:.3e} | {by_rmse:.2f}x | {by_rel:.2f}x |")


if __name__ == "__main__":
    main()
