# Builds scenes/cornell-box.json (or cornell-smoke.json) in Blender's Cycles and renders it headless on the CPU, for
# BENCHMARKS.md "Light sampling": diffuse BSDFs, two-sided emission, a box pixel filter one pixel wide, 50 bounces of
# every kind, no denoising, no clamping, no adaptive sampling. Writes the linear radiance as PFM and prints the render time.
# Usage: blender -b --factory-startup --python tools/peers/cycles_cornell.py -- SCENE.json WIDTH HEIGHT SPP THREADS OUT.pfm
import json
import math
import struct
import sys
import time

import bpy
import mathutils

args = sys.argv[sys.argv.index("--") + 1:]
scene_path, width, height, spp, threads, out_path = args[0], int(args[1]), int(args[2]), int(args[3]), int(args[4]), args[5]
description = json.load(open(scene_path))

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
cycles = scene.cycles
cycles.device = "CPU"
cycles.samples = spp
cycles.use_adaptive_sampling = False
cycles.use_denoising = False
cycles.max_bounces = cycles.diffuse_bounces = cycles.glossy_bounces = cycles.transmission_bounces = 50
cycles.volume_bounces = cycles.transparent_max_bounces = 50
cycles.sample_clamp_direct = cycles.sample_clamp_indirect = 0.0
cycles.pixel_filter_type = "BOX"
cycles.filter_width = 1.0
cycles.seed = 3
scene.render.threads_mode = "FIXED"
scene.render.threads = threads
scene.render.resolution_x, scene.render.resolution_y = width, height
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
scene.view_settings.view_transform = "Standard"

world = bpy.data.worlds.new("black")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
scene.world = world


def material(name, spec):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    nodes.clear()
    output = nodes.new("ShaderNodeOutputMaterial")
    if spec["type"] == "lambertian":
        bsdf = nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*spec["albedo"], 1.0)
        links.new(bsdf.outputs[0], output.inputs["Surface"])
    elif spec["type"] == "diffuse_light":
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        emission.inputs["Strength"].default_value = spec["emission"][0]
        assert spec["emission"][0] == spec["emission"][1] == spec["emission"][2]
        links.new(emission.outputs[0], output.inputs["Surface"])
    elif spec["type"] == "isotropic":
        # Extinction `density` with single-scattering albedo a: scattering a x density (Volume Scatter's colour times
        # its density) plus absorption (1 - a) x density (Volume Absorption absorbs 1 - its colour).
        scatter = nodes.new("ShaderNodeVolumeScatter")
        scatter.inputs["Color"].default_value = (*spec["albedo"], 1.0)
        scatter.inputs["Anisotropy"].default_value = 0.0
        absorption = nodes.new("ShaderNodeVolumeAbsorption")
        absorption.inputs["Color"].default_value = (*spec["albedo"], 1.0)
        both = nodes.new("ShaderNodeAddShader")
        links.new(scatter.outputs[0], both.inputs[0])
        links.new(absorption.outputs[0], both.inputs[1])
        links.new(both.outputs[0], output.inputs["Volume"])
        return m, (scatter, absorption)
    else:
        raise SystemExit(f"material type {spec['type']} is not translated")
    return m, None


materials = {name: material(name, spec)[0] for name, spec in description.get("materials", {}).items()}


def add_mesh(name, vertices, faces, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.data.materials.append(mat)
    scene.collection.objects.link(obj)
    return obj


def box_vertices(lo, hi, transform):
    corners = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    rotation = mathutils.Euler([math.radians(a) for a in transform.get("rotate", [0, 0, 0])], "XYZ").to_matrix()
    offset = mathutils.Vector(transform.get("translate", [0, 0, 0]))
    return [tuple(rotation @ mathutils.Vector(c) + offset) for c in corners]


# Corners indexed by (x, y, z) bits as above: x*4 + y*2 + z.
BOX_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]

for index, obj in enumerate(description["objects"]):
    kind = obj["type"]
    if kind == "quad":
        c, u, v = (mathutils.Vector(obj[k]) for k in ("corner", "u", "v"))
        add_mesh(f"quad{index}", [tuple(c), tuple(c + u), tuple(c + u + v), tuple(c + v)], [(0, 1, 2, 3)], materials[obj["material"]])
    elif kind == "box":
        add_mesh(f"box{index}", box_vertices(obj["min"], obj["max"], obj.get("transform", {})), BOX_FACES, materials[obj["material"]])
    elif kind == "medium":
        boundary = obj["boundary"]
        assert boundary["type"] == "box"
        m, (scatter, absorption) = material(f"medium{index}", obj["material"])
        scatter.inputs["Density"].default_value = absorption.inputs["Density"].default_value = obj["density"]
        # Only the volume: the boundary itself is invisible (a transparent surface).
        m.node_tree.nodes.new("ShaderNodeBsdfTransparent")
        m.node_tree.links.new(m.node_tree.nodes["Transparent BSDF"].outputs[0], m.node_tree.nodes["Material Output"].inputs["Surface"])
        # Inset by 0.01 (of 165 or more): a boundary face that lies on the floor would fight with it in Cycles,
        # where a medium's boundary is a surface; here it is not.
        lo = [a + 0.01 for a in boundary["min"]]
        hi = [a - 0.01 for a in boundary["max"]]
        add_mesh(f"medium{index}", box_vertices(lo, hi, boundary.get("transform", obj.get("transform", {}))), BOX_FACES, m)
    else:
        raise SystemExit(f"object type {kind} is not translated")

camera_spec = description["camera"]
camera_data = bpy.data.cameras.new("camera")
camera_data.sensor_fit = "VERTICAL"
camera_data.angle_y = math.radians(camera_spec["vertical_fov"])
camera_data.clip_start, camera_data.clip_end = 1e-3, 1e7  # the default 1000 would cut the scene
camera = bpy.data.objects.new("camera", camera_data)
eye, target = mathutils.Vector(camera_spec["look_from"]), mathutils.Vector(camera_spec["look_at"])
camera.location = eye
camera.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
scene.collection.objects.link(camera)
scene.camera = camera

scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
exr_path = out_path + ".exr"
scene.render.filepath = exr_path
start = time.perf_counter()
bpy.ops.render.render(write_still=True)
print(f"cycles render seconds {time.perf_counter() - start:.3f}")

image = bpy.data.images.load(exr_path)
pixels = list(image.pixels)  # RGBA, rows from the bottom, as PFM stores them
with open(out_path, "wb") as f:
    f.write(f"PF\n{width} {height}\n-1.0\n".encode())
    rgb = [pixels[i + c] for i in range(0, len(pixels), 4) for c in range(3)]
    f.write(struct.pack(f"<{len(rgb)}f", *rgb))
