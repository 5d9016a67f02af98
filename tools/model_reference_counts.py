#!/usr/bin/env python3
"""Counts and bounds of PLY and OBJ model files, computed apart from the C++ readers, for the values their tests
check (tests/test_ply_obj_readers.cpp).

    tools/model_reference_counts.py /usr/share/assimp/models/PLY/cube.ply /usr/share/assimp/models/OBJ/box.obj

For each file: meshes, triangles (a polygon of n >= 3 vertices is n - 2 triangles, lines, points and faces of fewer
than 3 vertices make none), vertices (PLY: the vertex element's count; OBJ: distinct position/uv/normal index
triples within each mesh, a mesh being what a `g` or `o` statement starts) and the bounds of the positions the
faces use. Only what the test files need is read: no MTL, no texture, no error checks.
"""
import struct
import sys

PLY_TYPES = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h", "ushort": "H", "uint16": "H",
    "int": "i", "int32": "i", "uint": "I", "uint32": "I", "float": "f", "float32": "f", "double": "d", "float64": "d",
}


def bounds(points):
    return [min(p[i] for p in points) for i in range(3)], [max(p[i] for p in points) for i in range(3)]


def ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header")
    body_start = data.index(b"\n", end) + 1
    header = data[:end].decode("latin-1").splitlines()
    fmt = header[1].split()[1]
    elements = []
    for line in header:
        words = line.split()
        if words and words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words and words[0] == "property":
            elements[-1][2].append(words[1:])
    positions, faces = [], []
    if fmt == "ascii":
        tokens = data[body_start:].split()
        at = 0
        for name, count, props in elements:
            for _ in range(count):
                values = {}
                for prop in props:
                    if prop[0] == "list":
                        n = int(tokens[at])
                        values[prop[3]] = [int(t) for t in tokens[at + 1:at + 1 + n]]
                        at += 1 + n
                    else:
                        values[prop[1]] = float(tokens[at])
                        at += 1
                if name == "vertex":
                    positions.append((values["x"], values["y"], values["z"]))
                elif name == "face":
                    faces.append(values.get("vertex_indices", values.get("vertex_index")))
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        at = body_start
        for name, count, props in elements:
            for _ in range(count):
                values = {}
                for prop in props:
                    if prop[0] == "list":
                        (n,) = struct.unpack_from(order + PLY_TYPES[prop[1]], data, at)
                        at += struct.calcsize(PLY_TYPES[prop[1]])
                        item = PLY_TYPES[prop[2]]
                        values[prop[3]] = list(struct.unpack_from(order + item * n, data, at))
                        at += n * struct.calcsize(item)
                    else:
                        (values[prop[1]],) = struct.unpack_from(order + PLY_TYPES[prop[0]], data, at)
                        at += struct.calcsize(PLY_TYPES[prop[0]])
                if name == "vertex":
                    positions.append((values["x"], values["y"], values["z"]))
                elif name == "face":
                    faces.append(values.get("vertex_indices", values.get("vertex_index")))
    triangles = sum(len(f) - 2 for f in faces if len(f) >= 3)
    used = [positions[i] for f in faces if len(f) >= 3 for i in f]
    print(f"{path}: 1 mesh, {triangles} triangles, {len(positions)} vertices, "
          f"{len(faces)} faces ({sum(1 for f in faces if len(f) < 3)} of fewer than 3 vertices)")
    if used:
        print("  bounds", *bounds(used))


def obj(path):
    positions, uvs, normals = 0, 0, 0
    points = []
    meshes = []  # (triangles, set of index triples)
    current = [0, set()]
    for raw in open(path, "rb").read().decode("latin-1").replace("\r\n", "\n").replace("\r", "\n").split("\n"):
        words = raw.split()
        if not words:
            continue
        if words[0] == "v":
            points.append(tuple(float_prefix(w) for w in (words[1:4] + ["0", "0", "0"])[:3]))
        elif words[0] == "vt":
            uvs += 1
        elif words[0] == "vn":
            normals += 1
        elif words[0] in ("g", "o"):
            if current[0]:
                meshes.append(current)
            current = [0, set()]
        elif words[0] == "f" and len(words) >= 4:
            current[0] += len(words) - 3
            for word in words[1:]:
                parts = (word.split("/") + ["", ""])[:3]
                v = int(parts[0])
                vt = int(parts[1]) if parts[1] else 0
                vn = int(parts[2]) if parts[2] else 0
                # negative indices count back from the last one read so far
                v = v - 1 if v > 0 else len(points) + v
                vt = vt - 1 if vt > 0 else (uvs + vt if vt < 0 else -1)
                vn = vn - 1 if vn > 0 else (normals + vn if vn < 0 else -1)
                current[1].add((v, vt, vn))
    if current[0]:
        meshes.append(current)
    used = [points[key[0]] for mesh in meshes for key in mesh[1]]
    print(f"{path}: {len(meshes)} meshes, {sum(m[0] for m in meshes)} triangles, "
          f"{sum(len(m[1]) for m in meshes)} vertices; per mesh (triangles, vertices): {[(m[0], len(m[1])) for m in meshes]}")
    if used:
        print("  bounds", *bounds(used))


def float_prefix(word):
    """The number a word starts with (OBJ readers take `3.1+e2` as 3.1)."""
    for end in range(len(word), 0, -1):
        try:
            return float(word[:end])
        except ValueError:
            pass
    return 0.0


for argument in sys.argv[1:]:
    try:
        (ply if argument.lower().endswith(".ply") else obj)(argument)
    except (struct.error, IndexError, ValueError) as error:
        print(f"{argument}: cannot read: {error}")
