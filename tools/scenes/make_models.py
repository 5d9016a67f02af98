"""Writes the model files the shipped scenes place (scenes/models/): pure Python 3, no dependencies.

  knot.ply     a (3, 2) torus knot as a tube, 3,072 triangles with normals and texture coordinates (ASCII PLY)
  pedestal.gltf  a bevelled box with two materials, buffers embedded as a data URI (glTF 2.0)
  ring.ply     a napkin ring: a short tube with inner and outer walls and flat rims, 1,024 triangles with normals

Usage: python3 tools/scenes/make_models.py [--out scenes/models]
"""

import argparse
import base64
import json
import math
import struct
from pathlib import Path


def knot(path, turns=128, sides=12, tube=0.18):
    """A tube around the (3, 2) torus knot, with vertex normals and uvs."""
    def centre(t):
        r = 0.5 * (2 + math.cos(3 * t))
        return (r * math.cos(2 * t), r * math.sin(2 * t), 0.5 * -math.sin(3 * t))

    vertices = []
    for i in range(turns):
        t = 2 * math.pi * i / turns
        c, n = centre(t), centre(t + 1e-4)
        tangent = [n[k] - c[k] for k in range(3)]
        length = math.sqrt(sum(x * x for x in tangent))
        tangent = [x / length for x in tangent]
        up = (0.0, 0.0, 1.0)
        side = [tangent[1] * up[2] - tangent[2] * up[1], tangent[2] * up[0] - tangent[0] * up[2], tangent[0] * up[1] - tangent[1] * up[0]]
        length = math.sqrt(sum(x * x for x in side))
        side = [x / length for x in side]
        other = [side[1] * tangent[2] - side[2] * tangent[1], side[2] * tangent[0] - side[0] * tangent[2], side[0] * tangent[1] - side[1] * tangent[0]]
        for j in range(sides):
            a = 2 * math.pi * j / sides
            normal = [math.cos(a) * side[k] + math.sin(a) * other[k] for k in range(3)]
            position = [c[k] + tube * normal[k] for k in range(3)]
            vertices.append((position, normal, (i / turns, j / sides)))
    faces = []
    for i in range(turns):
        for j in range(sides):
            a = i * sides + j
            b = ((i + 1) % turns) * sides + j
            c = ((i + 1) % turns) * sides + (j + 1) % sides
            d = i * sides + (j + 1) % sides
            faces.append((a, b, c, d))  # quads: the reader cuts them into two triangles each
    with open(path, "w") as out:
        out.write("ply\nformat ascii 1.0\ncomment a (3, 2) torus knot, tools/scenes/make_models.py\n")
        out.write(f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n")
        out.write("property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n")
        out.write(f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
        for p, n, uv in vertices:
            out.write(" ".join(f"{x:.6f}" for x in (*p, *n, *uv)) + "\n")
        for f in faces:
            out.write(f"4 {f[0]} {f[1]} {f[2]} {f[3]}\n")


def ring(path, segments=128, outer=1.0, inner=0.94, height=0.35):
    """An upright band standing on y = 0: its inner wall, a concave mirror when made of metal, draws a caustic."""
    vertices, faces = [], []

    def strip(radius_a, y_a, radius_b, y_b, normal_of):
        first = len(vertices)
        for i in range(segments):
            a = 2 * math.pi * i / segments
            c, s = math.cos(a), math.sin(a)
            n = normal_of(c, s)
            vertices.append(((radius_a * c, y_a, radius_a * s), n))
            vertices.append(((radius_b * c, y_b, radius_b * s), n))
        for i in range(segments):
            j = (i + 1) % segments
            faces.append((first + 2 * i, first + 2 * i + 1, first + 2 * j + 1, first + 2 * j))

    strip(outer, 0.0, outer, height, lambda c, s: (c, 0.0, s))  # outer wall
    strip(inner, height, inner, 0.0, lambda c, s: (-c, 0.0, -s))  # inner wall
    strip(outer, height, inner, height, lambda c, s: (0.0, 1.0, 0.0))  # top rim
    strip(inner, 0.0, outer, 0.0, lambda c, s: (0.0, -1.0, 0.0))  # bottom rim
    with open(path, "w") as out:
        out.write("ply\nformat ascii 1.0\ncomment a napkin ring, tools/scenes/make_models.py\n")
        out.write(f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n")
        out.write("property float nx\nproperty float ny\nproperty float nz\n")
        out.write(f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
        for p, n in vertices:
            out.write(" ".join(f"{x:.6f}" for x in (*p, *n)) + "\n")
        for f in faces:
            out.write(f"4 {f[0]} {f[1]} {f[2]} {f[3]}\n")


def pedestal(path):
    """A box 2 x 0.4 x 2 (top at y = 0) with a light top inset: two primitives, two materials."""
    positions, normals, indices_body, indices_top = [], [], [], []

    def quad(corner, u, v, normal, target):
        base = len(positions)
        for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
            positions.append([corner[k] + a * u[k] + b * v[k] for k in range(3)])
            normals.append(list(normal))
        target.extend([base, base + 1, base + 2, base, base + 2, base + 3])

    lo, hi = (-1.0, -0.4, -1.0), (1.0, 0.0, 1.0)
    sx, sy, sz = hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]
    quad((lo[0], lo[1], hi[2]), (sx, 0, 0), (0, sy, 0), (0, 0, 1), indices_body)
    quad((hi[0], lo[1], lo[2]), (-sx, 0, 0), (0, sy, 0), (0, 0, -1), indices_body)
    quad((hi[0], lo[1], hi[2]), (0, 0, -sz), (0, sy, 0), (1, 0, 0), indices_body)
    quad((lo[0], lo[1], lo[2]), (0, 0, sz), (0, sy, 0), (-1, 0, 0), indices_body)
    quad((lo[0], lo[1], lo[2]), (sx, 0, 0), (0, 0, sz), (0, -1, 0), indices_body)
    quad((lo[0], hi[1], hi[2]), (sx, 0, 0), (0, 0, -sz), (0, 1, 0), indices_top)
    blob = b"".join(struct.pack("<3f", *p) for p in positions) + b"".join(struct.pack("<3f", *n) for n in normals)
    index_offset = len(blob)
    blob += b"".join(struct.pack("<H", i) for i in indices_body + indices_top)
    while len(blob) % 4:
        blob += b"\0"
    count = len(positions)
    gltf = {
        "asset": {"version": "2.0", "generator": "tools/scenes/make_models.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "pedestal"}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0},
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 3, "material": 1}]}],
        "materials": [
            {"name": "stone", "pbrMetallicRoughness": {"baseColorFactor": [0.55, 0.5, 0.45, 1], "metallicFactor": 0, "roughnessFactor": 1}},
            {"name": "top", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.25, 0.6, 1], "metallicFactor": 0, "roughnessFactor": 1}}],
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 12 * count},
            {"buffer": 0, "byteOffset": 12 * count, "byteLength": 12 * count},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": 2 * len(indices_body)},
            {"buffer": 0, "byteOffset": index_offset + 2 * len(indices_body), "byteLength": 2 * len(indices_top)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3", "min": list(lo), "max": list(hi)},
            {"bufferView": 1, "componentType": 5126, "count": count, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": len(indices_body), "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5123, "count": len(indices_top), "type": "SCALAR"}],
    }
    with open(path, "w") as out:
        json.dump(gltf, out, indent=1)
        out.write("\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="scenes/models")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    knot(out / "knot.ply")
    pedestal(out / "pedestal.gltf")
    ring(out / "ring.ply")


if __name__ == "__main__":
    main()
