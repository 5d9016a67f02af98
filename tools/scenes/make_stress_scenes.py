"""Writes large and hostile scene files for measuring the parser's cost (BENCHMARKS.md, "Scene loading").

Not shipped data: the files are generated where asked (default: /tmp/pathtracer-stress). Pure Python 3; a fixed
seed makes them reproducible.

  spheres-1m.json        1,000,000 small spheres with named materials (about 80 MB)
  spheres-225mb.json     the same kind of scene grown to about 225 MB (about 2.5 million spheres), valid
  spheres-225mb-bad-tail.json     that scene with a syntax error in its last bytes
  spheres-225mb-bad-last.json     that scene with a negative radius in its last object
  nested-100k.json       arrays nested 100,000 deep

Usage: python3 tools/scenes/make_stress_scenes.py [--out FOLDER]
"""

import argparse
import random
from pathlib import Path

HEAD = """{
  "render": {"width": 64, "height": 48, "samples_per_pixel": 1, "max_depth": 4},
  "camera": {"look_from": [0, 20, 120], "look_at": [0, 0, 0], "vertical_fov": 40},
  "materials": {
    "m0": {"type": "lambertian", "albedo": [0.8, 0.3, 0.3]},
    "m1": {"type": "metal", "albedo": [0.8, 0.8, 0.9], "fuzz": 0.1},
    "m2": {"type": "dielectric", "ior": 1.5},
    "m3": {"type": "lambertian", "albedo": [0.2, 0.6, 0.3]}
  },
  "objects": [
"""


def sphere_lines(count, rng):
    for i in range(count):
        x, y, z = (round(rng.uniform(-100, 100), 3) for _ in range(3))
        yield f'{{"type": "sphere", "center": [{x}, {y}, {z}], "radius": 0.2, "material": "m{i % 4}"}}'


def write_spheres(path, count, last=None, tail="\n  ]\n}\n"):
    rng = random.Random(14)
    with open(path, "w") as out:
        out.write(HEAD)
        lines = sphere_lines(count, rng)
        first = True
        for line in lines:
            if not first:
                out.write(",\n")
            out.write(line)
            first = False
        if last is not None:
            out.write(",\n" + last)
        out.write(tail)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="/tmp/pathtracer-stress")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_spheres(out / "spheres-1m.json", 1_000_000)
    big = 2_500_000
    write_spheres(out / "spheres-225mb.json", big)
    write_spheres(out / "spheres-225mb-bad-tail.json", big, tail="\n  ]\n}\n}")
    write_spheres(out / "spheres-225mb-bad-last.json", big,
                  last='{"type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "m0"}')
    depth = 100_000
    (out / "nested-100k.json").write_text("[" * depth + "]" * depth + "\n")
    for f in sorted(out.iterdir()):
        print(f"{f}: {f.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
