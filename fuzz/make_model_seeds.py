#!/usr/bin/env python3
"""Writes the seed corpora of the model file fuzz targets: small valid PLY files in each encoding (with lists,
unknown elements and properties, every scalar type) and small OBJ files (groups, polygons, negative indices, a
material library after a "#mtl" line, as fuzz_obj_reader.cpp splits its input).

    fuzz/make_model_seeds.py fuzz/corpus-ply_reader fuzz/corpus-obj_reader
"""
import os
import struct
import sys

SQUARE = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def ply_seeds():
    seeds = {}
    seeds["ascii-square.ply"] = (
        "ply\nformat ascii 1.0\ncomment a unit square\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n0 1 0 0 0 1 0 1\n4 0 1 2 3\n").encode()
    seeds["ascii-odd.ply"] = (
        "ply\r\nformat ascii 1.0\r\nobj_info written by hand\r\nelement face 3\r\nproperty uchar flags\r\n"
        "property list uint8 uint32 vertex_index\r\nelement edge 1\r\nproperty list int16 int8 ends\r\n"
        "element vertex 5\r\nproperty double x\r\nproperty float32 y\r\nproperty int16 z\r\nproperty uchar red\r\n"
        "property float s\r\nproperty float t\r\nend_header\r\n"
        "1 5 0 1 2 3 4\r\n0 2 0 1\r\n2 3 4 2 0\r\n2 0 1\r\n"
        "0 0 0 255 0 0\r\n1e0 0 1 128 1 0\r\n1 1.5 2 0 1 1\r\n-.5 1 -3 7 0 1\r\n0 +0.5 0 9 0.5 0.5\r\n").encode()
    header = ("ply\nformat {} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              "property uchar red\nelement material 1\nproperty list ushort char name\n"
              "element face 2\nproperty list uchar int vertex_indices\nproperty int8 flags\nend_header\n")
    for fmt, order in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        body = b""
        for x, y, z in SQUARE:
            body += struct.pack(order + "fffB", x, y, z, 200)
        body += struct.pack(order + "H", 3) + b"abc"
        body += struct.pack(order + "Biiib", 3, 0, 1, 2, -1) + struct.pack(order + "Biiib", 3, 0, 2, 3, 1)
        seeds[f"{fmt}.ply"] = header.format(fmt).encode() + body
    body = b"".join(struct.pack("<ddd", *p) for p in SQUARE) + struct.pack("<iHHHH", 4, 0, 1, 2, 3)
    seeds["binary-doubles.ply"] = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float64 x\nproperty float64 y\n"
        "property float64 z\nelement face 1\nproperty list int32 uint16 vertex_indices\nend_header\n").encode() + body
    return seeds


OBJ_MATERIALS = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
mtllib m.mtl
o lit
usemtl glow lamp
f 1/1/1 2/2/1 3/3/1
usemtl plain
f 1//1 3//1 4//1
g bare
usemtl undefined
f -4 -2 -1

#mtl
newmtl glow lamp
Kd 0.2 0.3 0.4
Ke 1 1 1
Pr 0.5
Pm 0.25
map_Ke t.png
newmtl plain
map_Kd -s 1 1 1 t.png
bump t.png
d 0.5
Ks 1 1 1
"""

OBJ_SEEDS = {
    "triangle.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "quad-uv-normals.obj": "# a square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n"
                           "f 1/1/1 2/1/1 3/2/1 4/2/1\nf -4//-1 -2//-1 -1//-1\n",
    "concave.obj": "o L\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 1 2 3 4 5 6\n",
    "statements.obj": "mtllib\ng\ng a b\ns 1\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvw 0 0 0.5\nt crease 2/1/0 1 2 0.5\n"
                      "l 1 2 3\np 1\nf 1 2\nf 3 2 1\ns off\no\nf 1 2 3\r\nf 1/1 2/1 3/1\n",
    "materials.obj": OBJ_MATERIALS,
    "big-polygon.obj": "".join(f"v {i % 7} {i % 11} 0\n" for i in range(12)) + "f " + " ".join(str(1 + i % 12) for i in range(260)) + "\n",
}


def main():
    ply_folder, obj_folder = sys.argv[1], sys.argv[2]
    os.makedirs(ply_folder, exist_ok=True)
    os.makedirs(obj_folder, exist_ok=True)
    for name, data in ply_seeds().items():
        with open(os.path.join(ply_folder, name), "wb") as out:
            out.write(data)
    for name, text in OBJ_SEEDS.items():
        with open(os.path.join(obj_folder, name), "wb") as out:
            out.write(text.encode())


main()
