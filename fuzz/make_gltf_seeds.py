#!/usr/bin/env python3
"""Writes the glTF fuzz target's seed corpus: a few small files that reach each part of the reader (data URIs, a
.glb with its image in a buffer view, external files, every primitive mode and index type, normalized texture
coordinates, node transforms, cameras, materials and extensions, skins, morph targets and animations) and two
broken ones. external.gltf names the files fuzz_gltf_reader.cpp writes beside each input: buffer.bin (a
triangle's positions, texture coordinates and unsigned short indices, 68 bytes) and texture.png (2x2 RGB).
Usage: fuzz/make_gltf_seeds.py OUTPUT_FOLDER"""
import base64
import json
import struct
import sys
import zlib
from pathlib import Path


def png_2x2():
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    rows = b"\x00" + bytes([255, 0, 0, 0, 255, 0]) + b"\x00" + bytes([0, 0, 255, 255, 255, 255])
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))


class Builder:
    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": []}
        self.bin = b""

    def view(self, data, stride=None):
        self.bin += b"\0" * (-len(self.bin) % 4)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            view["byteStride"] = stride
        self.doc["bufferViews"].append(view)
        self.bin += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, data, component_type, count, kind, normalized=False, stride=None):
        accessor = {"bufferView": self.view(data, stride), "componentType": component_type, "count": count, "type": kind}
        if normalized:
            accessor["normalized"] = True
        self.doc["accessors"].append(accessor)
        return len(self.doc["accessors"]) - 1

    def floats(self, values, kind):
        return self.accessor(struct.pack("<%df" % len(values), *values), 5126, len(values) // {"VEC2": 2, "VEC3": 3}[kind], kind)

    def as_gltf(self):
        doc = dict(self.doc)
        doc["buffers"] = [{"byteLength": len(self.bin), "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
        return json.dumps(doc, separators=(",", ":")).encode()

    def as_glb(self):
        doc = dict(self.doc)
        binary = self.bin + b"\0" * (-len(self.bin) % 4)
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        text = json.dumps(doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def triangle(with_image):
    b = Builder()
    p = b.floats([0, 0, 0, 1, 0, 0, 0, 1, 0], "VEC3")
    n = b.floats([0, 0, 1] * 3, "VEC3")
    t = b.floats([0, 0, 1, 0, 0, 1], "VEC2")
    i = b.accessor(struct.pack("<3H", 0, 1, 2), 5123, 3, "SCALAR")
    b.doc["meshes"] = [{"name": "tri", "primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i, "material": 0},
                                                      {"attributes": {"POSITION": p}, "mode": 4}]}]
    material = {"name": "glow", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1, 0.5], "metallicFactor": 0.5, "roughnessFactor": 0.25},
                "emissiveFactor": [1, 0.5, 0], "alphaMode": "BLEND",
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}}}
    if with_image:
        b.doc["images"] = [{"bufferView": b.view(png_2x2()), "mimeType": "image/png"}]
        b.doc["textures"] = [{"source": 0, "sampler": 0}]
        b.doc["samplers"] = [{"wrapS": 33071}]
        material["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
        material["emissiveTexture"] = {"index": 0, "texCoord": 0}
    b.doc["materials"] = [material]
    b.doc["extensionsUsed"] = ["KHR_materials_emissive_strength", "KHR_lights_punctual"]
    b.doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}},
                        {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 10}}]
    b.doc["nodes"] = [{"translation": [1, 2, 3], "rotation": [0, 0.7071068, 0, 0.7071068], "scale": [2, 2, 2], "children": [1, 2]},
                      {"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1]},
                      {"camera": 1, "children": [3]}, {"camera": 0, "translation": [0, 0, 5]}, {"mesh": 0, "scale": [1, 0, 1]}]
    b.doc["scenes"] = [{"nodes": [0, 4]}]
    b.doc["scene"] = 0
    return b


def modes():
    b = Builder()
    p = b.floats([0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0], "VEC3")
    uv8 = b.accessor(bytes([0, 0, 9, 9, 255, 0, 9, 9, 0, 255, 9, 9, 255, 255, 9, 9, 0, 128, 9, 9]), 5121, 5, "VEC2", normalized=True, stride=4)
    uv16 = b.accessor(struct.pack("<10H", 0, 0, 65535, 0, 0, 65535, 65535, 65535, 0, 32768), 5123, 5, "VEC2", normalized=True)
    i8 = b.accessor(bytes([0, 1, 2, 3, 4]), 5121, 5, "SCALAR")
    i16 = b.accessor(struct.pack("<5H", 4, 3, 2, 1, 0), 5123, 5, "SCALAR")
    i32 = b.accessor(struct.pack("<6I", 0, 1, 2, 2, 1, 3), 5125, 6, "SCALAR")
    b.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png_2x2()).decode()}]
    b.doc["textures"] = [{"source": 0}]
    b.doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}}, {"emissiveTexture": {"index": 0}}]
    b.doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": p}, "mode": m} for m in (0, 1, 2, 3)] +
                        [{"attributes": {"POSITION": p, "TEXCOORD_1": uv8}, "indices": i8, "mode": 5, "material": 0},
                         {"attributes": {"POSITION": p, "TEXCOORD_0": uv16}, "indices": i16, "mode": 6, "material": 1},
                         {"attributes": {"POSITION": p}, "indices": i32, "mode": 4}]}]
    b.doc["nodes"] = [{"mesh": 0}]
    return b


def animated():
    b = Builder()
    p = b.floats([0, 0, 0, 1, 0, 0, 0, 1, 0], "VEC3")
    d = b.floats([0, 0, 1] * 3, "VEC3")
    times = b.accessor(struct.pack("<2f", 0, 1), 5126, 2, "SCALAR")
    weights = b.accessor(struct.pack("<2f", 0, 1), 5126, 2, "SCALAR")
    b.doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": p}, "targets": [{"POSITION": d}]}], "weights": [0.5]}]
    b.doc["nodes"] = [{"mesh": 0, "skin": 0, "children": [1]}, {"translation": [0, 1, 0]}]
    b.doc["skins"] = [{"joints": [1]}]
    b.doc["animations"] = [{"samplers": [{"input": times, "output": weights}], "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}]
    return b


def external():
    # buffer.bin: positions at 0 (36 bytes), uvs at 36 (24), unsigned short indices at 60 (6 + 2 padding).
    doc = {"asset": {"version": "2.0"},
           "buffers": [{"uri": "buffer.bin", "byteLength": 68}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                           {"buffer": 0, "byteOffset": 60, "byteLength": 6}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                         {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
           "images": [{"uri": "texture.png"}], "textures": [{"source": 0}],
           "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
           "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]}
    return json.dumps(doc, separators=(",", ":")).encode()


def main():
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    (out / "triangle.gltf").write_bytes(triangle(False).as_gltf())
    (out / "textured.glb").write_bytes(triangle(True).as_glb())
    (out / "modes.gltf").write_bytes(modes().as_gltf())
    (out / "animated.gltf").write_bytes(animated().as_gltf())
    (out / "external.gltf").write_bytes(external())
    recursive = {"asset": {"version": "2.0"}, "nodes": [{"children": [1]}, {"children": [0]}], "scenes": [{"nodes": [0]}]}
    (out / "recursive.gltf").write_bytes(json.dumps(recursive).encode())
    broken = modes()  # its unsigned int indices name vertex 9 of 5
    view = broken.doc["bufferViews"][broken.doc["accessors"][5]["bufferView"]]
    start = view["byteOffset"]
    broken.bin = broken.bin[:start] + struct.pack("<6I", 0, 1, 2, 2, 1, 9) + broken.bin[start + 24:]
    (out / "index-out-of-range.glb").write_bytes(broken.as_glb())


if __name__ == "__main__":
    main()
