#!/usr/bin/env python3
"""Counts and bounds of a glTF 2.0 file, computed independently of the reader, for tests/test_gltf_reader.cpp.

Usage: tests/gltf_reference.py FILE.gltf|FILE.glb ...

For each file: the placements (one per node with a mesh in the scene: the default scene, else scene 0, else all
root nodes), the meshes placed (each counted once), their triangles and vertices as the reader stores them, and
the bounds of all placed vertices in the file's space. Vertices: a mesh stores each combination of POSITION,
NORMAL and TEXCOORD_n accessors its primitives use once; a primitive without valid normals, in a mesh where
another has them, gets three vertices of its own per triangle. Triangles: TRIANGLES count/3, TRIANGLE_STRIP and
TRIANGLE_FAN count-2; POINTS and LINES* are not drawn.
"""
import base64
import json
import math
import os
import struct
import sys
import urllib.parse

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
FORMATS = {5120: "b", 5121: "B", 5122: "h", 5123: "H", 5125: "I", 5126: "f"}


def load(path):
    data = open(path, "rb").read()
    if data[:4] == b"glTF":
        json_length = struct.unpack_from("<I", data, 12)[0]
        gltf = json.loads(data[20:20 + json_length])
        rest = 20 + json_length
        bin_chunk = data[rest + 8:rest + 8 + struct.unpack_from("<I", data, rest)[0]] if rest < len(data) else b""
    else:
        gltf = json.loads(data)
        bin_chunk = b""
    buffers = []
    for buffer in gltf.get("buffers", []):
        uri = buffer.get("uri")
        if uri is None:
            buffers.append(bin_chunk)
        elif uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            buffers.append(open(os.path.join(os.path.dirname(path), urllib.parse.unquote(uri)), "rb").read())
    return gltf, buffers


def read_accessor(gltf, buffers, index):
    accessor = gltf["accessors"][index]
    view = gltf["bufferViews"][accessor["bufferView"]]
    fmt = FORMATS[accessor["componentType"]]
    n = COMPONENTS[accessor["type"]]
    size = struct.calcsize("<" + fmt)
    stride = view.get("byteStride", size * n)
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    data = buffers[view["buffer"]]
    return [struct.unpack_from("<" + fmt * n, data, start + i * stride) for i in range(accessor["count"])]


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def local_matrix(node):
    if "matrix" in node:
        m = node["matrix"]
        return [[m[c * 4 + r] for c in range(4)] for r in range(4)]
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    sx, sy, sz = node.get("scale", [1, 1, 1])
    tx, ty, tz = node.get("translation", [0, 0, 0])
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    s = [sx, sy, sz]
    t = [tx, ty, tz]
    return [[r[i][j] * s[j] for j in range(3)] + [t[i]] for i in range(3)] + [[0, 0, 0, 1]]


def uv_set(gltf, material):
    if material is None:
        return None
    m = gltf["materials"][material]
    for info in (m.get("pbrMetallicRoughness", {}).get("baseColorTexture"), m.get("emissiveTexture")):
        if info is not None and "source" in gltf["textures"][info["index"]]:
            return info.get("texCoord", 0)
    return None


def mesh_counts(gltf, buffers, index):
    mesh = gltf["meshes"][index]
    sources = {}  # (position, normal, uv) -> (vertices, has valid normals)
    parts = []
    for primitive in mesh["primitives"]:
        mode = primitive.get("mode", 4)
        attributes = primitive["attributes"]
        if mode < 4 or "POSITION" not in attributes:
            continue
        position = attributes["POSITION"]
        normal = attributes.get("NORMAL")
        s = uv_set(gltf, primitive.get("material"))
        uv = attributes.get("TEXCOORD_%d" % s) if s is not None else None
        key = (position, normal, uv)
        vertices = gltf["accessors"][position]["count"]
        if key not in sources:
            good_normals = normal is not None and all(
                math.isfinite(math.hypot(*v)) and math.hypot(*v) >= 1e-12 for v in read_accessor(gltf, buffers, normal))
            sources[key] = (vertices, good_normals)
        count = gltf["accessors"][primitive["indices"]]["count"] if "indices" in primitive else vertices
        triangles = count // 3 if mode == 4 else max(count - 2, 0)
        parts.append((key, triangles))
    any_normals = any(sources[key][1] for key, _ in parts)
    vertex_count, triangle_count, placed = 0, 0, set()
    for key, triangles in parts:
        triangle_count += triangles
        if any_normals and not sources[key][1]:
            vertex_count += 3 * triangles
        elif key not in placed:
            placed.add(key)
            vertex_count += sources[key][0]
    positions = []
    for key in {key for key, _ in parts}:
        positions += read_accessor(gltf, buffers, key[0])
    return triangle_count, vertex_count, positions


def report(path):
    gltf, buffers = load(path)
    nodes = gltf.get("nodes", [])
    if "scene" in gltf or gltf.get("scenes"):
        roots = gltf["scenes"][gltf.get("scene", 0)].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    placements = []
    stack = [(r, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]) for r in reversed(roots)]
    while stack:
        index, parent = stack.pop()
        world = matmul(parent, local_matrix(nodes[index]))
        if "mesh" in nodes[index]:
            placements.append((nodes[index]["mesh"], world))
        for child in reversed(nodes[index].get("children", [])):
            stack.append((child, world))
    meshes = sorted({m for m, _ in placements})
    counts = {m: mesh_counts(gltf, buffers, m) for m in meshes}
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for m, world in placements:
        for p in counts[m][2]:
            q = [sum(world[i][j] * p[j] for j in range(3)) + world[i][3] for i in range(3)]
            lo = [min(a, b) for a, b in zip(lo, q)]
            hi = [max(a, b) for a, b in zip(hi, q)]
    print(path)
    print("  placements %d, meshes %d, triangles %d, vertices %d" % (
        len(placements), len(meshes), sum(c[0] for c in counts.values()), sum(c[1] for c in counts.values())))
    print("  per mesh (triangles, vertices): %s" % [(m, counts[m][0], counts[m][1]) for m in meshes])
    print("  bounds min (%.9g, %.9g, %.9g) max (%.9g, %.9g, %.9g)" % (*lo, *hi))


if __name__ == "__main__":
    for argument in sys.argv[1:]:
        report(argument)
