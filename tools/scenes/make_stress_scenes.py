"""Writes large and hostile scene files for measuring the parser's cost (BENCHMARKS.md, "Scene loading").

Not shipped data: the files are generated where asked (default: /tmp/pathtracer-stress). Pure Python 3; a fixed
seed makes them reproducible.

  spheres-1m.json        1,000,000 small spheres with named materials (about 80 MB)
  spheres-225mb.json     the same kind of scene grown to about 225 MB (about 2.5 million spheres), valid
  spheres-225mb-bad-tail.json     that scene with a syntax error in its last bytes
  spheres-225mb-bad-last.json     that scene with a negative radius in its last object
  spheres-inline-196mb.json       1,280,000 spheres each with its own inline Lambertian material (196 MB): the
                                  large scene whose render should take at most 10 s and twice the file's size
  nested-100k.json       arrays nested 100,000 deep
  bumpy-2m.ply           a bumpy sphere of 2,000,000 triangles (binary PLY, 50 MB), and bumpy-2m.json rendering it
  bumpy-instances.json   bumpy-1m.ply           the same with 1,000,000 triangles, and bumpy-1m.json: diffuse, for the GPU's 1M-triangle figure
  bumpy-200k.ply (200,000 triangles) placed 100 times: 20 million triangles as instances
  heightfield-1m.ply     a 708 x 708 grid of heights (999,698 triangles, binary PLY), and heightfield-1m.json seeing it
                         from above: the GPU issue's million-triangle height field

Usage: python3 tools/scenes/make_stress_scenes.py [--out FOLDER] [--meshes-only]
"""

import argparse
import math
import random
import struct
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


def inline_sphere_lines(count, rng):
    for _ in range(count):
        x, y, z = (round(rng.uniform(-100, 100), 4) for _ in range(3))
        radius = round(rng.uniform(0.1, 0.3), 3)
        r, g, b = (round(rng.uniform(0.05, 0.95), 4) for _ in range(3))
        yield (f'    {{"type": "sphere", "center": [{x}, {y}, {z}], "radius": {radius}, '
               f'"material": {{"type": "lambertian", "albedo": [{r}, {g}, {b}]}}}}')


def write_spheres(path, count, last=None, tail="\n  ]\n}\n", lines_of=sphere_lines):
    rng = random.Random(14)
    with open(path, "w") as out:
        out.write(HEAD)
        lines = lines_of(count, rng)
        first = True
        for line in lines:
            if not first:
                out.write(",\n")
            out.write(line)
            first = False
        if last is not None:
            out.write(",\n" + last)
        out.write(tail)


def large_scene(out):
    write_spheres(out / "spheres-inline-196mb.json", 1_280_000, lines_of=inline_sphere_lines)


def bumpy_sphere(path, rings):
    """A sphere of rings x 2 rings quads (two triangles each) with a bumpy radius, as binary little-endian PLY."""
    segments = 2 * rings
    with open(path, "wb") as out:
        out.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {(rings + 1) * (segments + 1)}\n"
                   "property float x\nproperty float y\nproperty float z\n"
                   f"element face {2 * rings * segments}\nproperty list uchar int vertex_indices\nend_header\n").encode())
        for r in range(rings + 1):
            theta = math.pi * r / rings
            row = bytearray()
            for s in range(segments + 1):
                phi = 2 * math.pi * s / segments
                radius = 1 + 0.02 * math.sin(40 * theta) * math.sin(40 * phi)
                row += struct.pack("<3f", radius * math.sin(theta) * math.cos(phi), radius * math.cos(theta), radius * math.sin(theta) * math.sin(phi))
            out.write(row)
        for r in range(rings):
            row = bytearray()
            for s in range(segments):
                a = r * (segments + 1) + s
                b = a + segments + 1
                row += struct.pack("<B3iB3i", 3, a, b, a + 1, 3, a + 1, b, b + 1)
            out.write(row)


def height_field(path, side):
    """A side x side grid of vertices over [-1, 1]^2 in x and z, heights of a few waves, as binary little-endian PLY."""
    with open(path, "wb") as out:
        out.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {side * side}\n"
                   "property float x\nproperty float y\nproperty float z\n"
                   f"element face {2 * (side - 1) * (side - 1)}\nproperty list uchar int vertex_indices\nend_header\n").encode())
        for i in range(side):
            z = -1 + 2 * i / (side - 1)
            row = bytearray()
            for j in range(side):
                x = -1 + 2 * j / (side - 1)
                y = 0.08 * math.sin(9 * x) * math.cos(7 * z) + 0.03 * math.sin(31 * x + 17 * z) + 0.01 * math.cos(83 * z - 61 * x)
                row += struct.pack("<3f", x, y, z)
            out.write(row)
        for i in range(side - 1):
            row = bytearray()
            for j in range(side - 1):
                a = i * side + j
                b = a + side
                row += struct.pack("<B3iB3i", 3, a, b, a + 1, 3, a + 1, b, b + 1)
            out.write(row)


MESH_SCENE = """{{
  "render": {{"width": 1280, "height": 720, "samples_per_pixel": 64, "max_depth": 8}},
  "camera": {{"look_from": [{eye}], "look_at": [{at}], "vertical_fov": 40}},
  "materials": {{"floor": {{"type": "lambertian", "albedo": [0.6, 0.6, 0.6]}}}},
  "objects": [
    {{"type": "quad", "corner": [-200, -1, -200], "u": [0, 0, 400], "v": [400, 0, 0], "material": "floor"}},
{objects}
  ]
}}
"""


def mesh_scenes(out):
    bumpy_sphere(out / "bumpy-2m.ply", 707)
    mesh = '    {"type": "mesh", "file": "bumpy-2m.ply", "material": {"type": "metal", "albedo": [0.9, 0.8, 0.6], "fuzz": 0.2}}'
    (out / "bumpy-2m.json").write_text(MESH_SCENE.format(eye="0, 1, 3.5", at="0, 0, 0", objects=mesh))
    bumpy_sphere(out / "bumpy-1m.ply", 500)
    mesh = '    {"type": "mesh", "file": "bumpy-1m.ply", "material": {"type": "lambertian", "albedo": [0.7, 0.6, 0.5]}}'
    (out / "bumpy-1m.json").write_text(MESH_SCENE.format(eye="0, 1, 3.5", at="0, 0, 0", objects=mesh))
    bumpy_sphere(out / "bumpy-200k.ply", 224)
    placed = []
    for i in range(10):
        for j in range(10):
            placed.append(f'    {{"type": "mesh", "file": "bumpy-200k.ply", "transform": {{"scale": 0.8, "rotate": [{7 * i}, {11 * j}, 0], '
                          f'"translate": [{2.2 * (i - 4.5):.1f}, 0, {-2.2 * j:.1f}]}}}}')
    (out / "bumpy-instances.json").write_text(MESH_SCENE.format(eye="0, 6, 9", at="0, 0, -8", objects=",\n".join(placed)))
    height_field(out / "heightfield-1m.ply", 708)
    mesh = '    {"type": "mesh", "file": "heightfield-1m.ply", "material": {"type": "lambertian", "albedo": [0.6, 0.7, 0.5]}}'
    (out / "heightfield-1m.json").write_text(MESH_SCENE.format(eye="0, 2.2, 0.6", at="0, 0, 0", objects=mesh))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="/tmp/pathtracer-stress")
    parser.add_argument("--meshes-only", action="store_true", help="only the mesh scenes (bumpy spheres, the height field)")
    parser.add_argument("--large-only", action="store_true", help="only the 196 MB scene of inline materials")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.large_only:
        large_scene(out)
        return
    mesh_scenes(out)
    if args.meshes_only:
        return
    write_spheres(out / "spheres-1m.json", 1_000_000)
    big = 2_500_000
    write_spheres(out / "spheres-225mb.json", big)
    write_spheres(out / "spheres-225mb-bad-tail.json", big, tail="\n  ]\n}\n}")
    write_spheres(out / "spheres-225mb-bad-last.json", big,
                  last='{"type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "m0"}')
    large_scene(out)
    depth = 100_000
    (out / "nested-100k.json").write_text("[" * depth + "]" * depth + "\n")
    for f in sorted(out.iterdir()):
        print(f"{f}: {f.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
