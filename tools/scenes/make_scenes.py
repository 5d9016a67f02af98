"""Writes the shipped JSON scenes into scenes/ (format: docs/scene-format.md).

Pure Python 3 (standard library only). Random scenes use Python's random.Random with fixed seeds, so the
files are reproducible. The seed's default scene takes its 482 small spheres from a list in the seed
reference format (`S a b lam c=(x,y,z) alb=(r,g,b)` ...), given with --seed-spheres; without it, the
spheres already in scenes/seed-default.json are kept, with their numbers exactly as written there.

Usage: python3 tools/scenes/make_scenes.py [--seed-spheres FILE] [--out FOLDER]
"""

import argparse
import json
import math
import random
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SKY = {"type": "sky", "horizon": [1, 1, 1], "zenith": [0.5, 0.7, 1.0]}
BLACK = {"type": "constant", "color": [0, 0, 0]}


# ----------------------------------------------------------------------------------------------------------
# JSON output: one key per line at the top, one object per line in the long lists
# ----------------------------------------------------------------------------------------------------------

class Number(str):
    """A number written exactly as given (for values copied from a list, e.g. "0.200000")."""

    _pattern = re.compile(r"-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?\Z")

    def __new__(cls, text):
        if not cls._pattern.match(text):
            raise ValueError(f"not a JSON number: {text!r}")
        return super().__new__(cls, text)


def r6(x):
    """Generated values are rounded to 6 decimals."""
    x = round(x, 6)
    return 0.0 if x == 0 else x


def compact(value):
    """One-line JSON with spaces after separators."""
    if isinstance(value, Number):
        return str(value)
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError("scene files hold finite numbers only")
        return repr(value)
    if isinstance(value, (int, str)):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {compact(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(compact(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__}")


def dump_scene(scene):
    """Top-level sections one key per line; textures, materials and objects one entry per line."""
    lines = ["{"]
    sections = list(scene.items())
    for n, (key, value) in enumerate(sections):
        comma = "," if n + 1 < len(sections) else ""
        if isinstance(value, dict) and value and key != "background":
            entries = list(value.items())
            lines.append(f"  {json.dumps(key)}: {{")
            for m, (k, v) in enumerate(entries):
                lines.append(f"    {json.dumps(k)}: {compact(v)}" + ("," if m + 1 < len(entries) else ""))
            lines.append("  }" + comma)
        elif isinstance(value, list):
            lines.append(f"  {json.dumps(key)}: [")
            for m, v in enumerate(value):
                lines.append(f"    {compact(v)}" + ("," if m + 1 < len(value) else ""))
            lines.append("  ]" + comma)
        else:
            lines.append(f"  {json.dumps(key)}: {compact(value)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------------------
# Small constructors
# ----------------------------------------------------------------------------------------------------------

def sphere(center, radius, material, **extra):
    return {"type": "sphere", "center": center, "radius": radius, "material": material, **extra}


def quad(corner, u, v, material):
    return {"type": "quad", "corner": corner, "u": u, "v": v, "material": material}


def box(lo, hi, material=None, transform=None):
    obj = {"type": "box", "min": lo, "max": hi}
    if material is not None:
        obj["material"] = material
    if transform is not None:
        obj["transform"] = transform
    return obj


def medium(boundary, density, albedo):
    return {"type": "medium", "boundary": boundary, "density": density,
            "material": {"type": "isotropic", "albedo": albedo}}


def lambertian(albedo):
    return {"type": "lambertian", "albedo": albedo}


def metal(albedo, fuzz):
    return {"type": "metal", "albedo": albedo, "fuzz": fuzz}


# ----------------------------------------------------------------------------------------------------------
# The seed implementation's default scene (shared/reference/README.md, "The seed's default scene, exactly")
# ----------------------------------------------------------------------------------------------------------

_NUM = r"(-?[0-9]+(?:\.[0-9]+)?)"
_VEC = rf"\({_NUM},{_NUM},{_NUM}\)"
_SPHERE_LINES = [
    ("lam", re.compile(rf"S -?\d+ -?\d+ lam c={_VEC} alb={_VEC}\Z")),
    ("movlam", re.compile(rf"S -?\d+ -?\d+ movlam c0={_VEC} c1y={_NUM} alb={_VEC}\Z")),
    ("metal", re.compile(rf"S -?\d+ -?\d+ metal c={_VEC} alb={_VEC} fuzz={_NUM}\Z")),
    ("glass", re.compile(rf"S -?\d+ -?\d+ glass c={_VEC}\Z")),
]
SEED_SMALL_RADIUS = 0.2
SEED_SPHERE_COUNT = 482


def parse_seed_spheres(text):
    """The small spheres of a list in the seed reference format, numbers kept as written."""
    objects = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        for kind, pattern in _SPHERE_LINES:
            m = pattern.match(line)
            if m:
                break
        else:
            raise ValueError(f"line {number}: not a sphere of the seed list: {line!r}")
        v = [Number(g) for g in m.groups()]
        if kind == "lam":
            objects.append(sphere(v[0:3], SEED_SMALL_RADIUS, lambertian(v[3:6])))
        elif kind == "movlam":
            objects.append({"type": "moving_sphere", "center0": v[0:3], "center1": [v[0], v[3], v[2]],
                            "radius": SEED_SMALL_RADIUS, "material": lambertian(v[4:7])})
        elif kind == "metal":
            objects.append(sphere(v[0:3], SEED_SMALL_RADIUS, metal(v[3:6], v[6])))
        else:
            objects.append(sphere(v[0:3], SEED_SMALL_RADIUS, "glass"))
    if len(objects) != SEED_SPHERE_COUNT:
        raise ValueError(f"expected {SEED_SPHERE_COUNT} spheres, found {len(objects)}")
    return objects


def spheres_from_existing(path):
    """The small spheres of an existing seed-default.json (objects 2 to 483), numbers kept as written."""
    scene = json.loads(path.read_text(), parse_float=Number)
    return scene["objects"][1:1 + SEED_SPHERE_COUNT]


def seed_default(small_spheres):
    apex = [6.25, 0.5, 1.05]
    objects = [sphere([0, -1000, 0], 1000, "ground")]
    objects += small_spheres
    objects += [
        {"type": "triangle", "vertices": [[6.5, 0, 1.3], apex, [6.5, 0, 0.8]],
         "material": lambertian([0.68, 0.5, 0.1])},
        {"type": "triangle", "vertices": [[6, 0, 1.3], apex, [6.5, 0, 1.3]],
         "material": lambertian([0.89, 0.73, 0.29])},
        {"type": "triangle", "vertices": [[6.5, 0, 0.8], apex, [6, 0, 0.8]], "material": "pyramid_blue"},
        {"type": "triangle", "vertices": [[6, 0, 0.8], apex, [6, 0, 1.3]], "material": "pyramid_blue"},
        sphere([4, 1, 0], 0.2, {"type": "diffuse_light", "emission": [10, 0, 10]}),
        quad([2, 0, -1], [2, 0, 0], [0, 1, 0], "logo"),
        sphere([4, 1, 2.25], 1, "logo"),
        sphere([0, 1, 0], 1, {"type": "dielectric", "ior": 1.5, "tint": [1, 0.5, 0.5]}),
        sphere([-4, 1, 0], 1, lambertian([0.4, 0.2, 0.1])),
        sphere([0, 1, -2.25], 1, metal([0.7, 0.6, 0.5], 0)),
        sphere([-60, 3, 5], 4, {"type": "lambertian", "texture": "banner"}),
        box([6.5, 0, -1.5], [7, 3, -1], metal([0.7, 0.6, 0.5], 0.25)),
        medium({"type": "sphere", "center": [5, 1, 3.5], "radius": 1}, 1, [1, 1, 1]),
    ]
    assert len(objects) == 496
    return {
        "render": {"width": 800, "height": 480, "samples_per_pixel": 100, "max_depth": 50},
        "camera": {"look_from": [13, 3, 3], "look_at": [0, -1, 0], "up": [0, 1, 0], "vertical_fov": 40,
                   "aperture": 0.04, "focus_distance": math.sqrt(194), "shutter": [0, 1]},
        "background": SKY,
        "textures": {
            "ground_checker": {"type": "checker", "odd": [0.2, 0.3, 0.1], "even": [0.9, 0.9, 0.9],
                               "frequency": 10},
            "logo": {"type": "image", "file": "textures/pathtracer-logo-1024x512.png", "repeat": 1},
            "banner": {"type": "image", "file": "textures/pathtracer-banner-1280x559.png", "repeat": 5},
        },
        "materials": {
            "ground": {"type": "lambertian", "texture": "ground_checker"},
            "glass": {"type": "dielectric", "ior": 1.5, "tint": [1, 1, 1]},
            "pyramid_blue": lambertian([0, 0, 1]),
            "logo": {"type": "lambertian", "texture": "logo"},
        },
        "objects": objects,
    }


# ----------------------------------------------------------------------------------------------------------
# "Ray Tracing in One Weekend", final scene
# ----------------------------------------------------------------------------------------------------------

def book1_final():
    rng = random.Random(2024)
    rnd = rng.random
    objects = [sphere([0, -1000, 0], 1000, lambertian([0.5, 0.5, 0.5]))]
    for a in range(-11, 11):
        for b in range(-11, 11):
            choose = rnd()
            x = a + 0.9 * rnd()
            z = b + 0.9 * rnd()
            center = [r6(x), 0.2, r6(z)]
            if math.dist((x, 0.2, z), (4, 0.2, 0)) <= 0.9:
                continue
            if choose < 0.8:
                albedo = [r6(rnd() * rnd()) for _ in range(3)]
                objects.append(sphere(center, 0.2, lambertian(albedo)))
            elif choose < 0.95:
                albedo = [r6(0.5 + 0.5 * rnd()) for _ in range(3)]
                objects.append(sphere(center, 0.2, metal(albedo, r6(0.5 * rnd()))))
            else:
                objects.append(sphere(center, 0.2, "glass"))
    objects += [
        sphere([0, 1, 0], 1, "glass"),
        sphere([-4, 1, 0], 1, lambertian([0.4, 0.2, 0.1])),
        sphere([4, 1, 0], 1, metal([0.7, 0.6, 0.5], 0)),
    ]
    return {
        "render": {"width": 1200, "height": 800, "samples_per_pixel": 100, "max_depth": 50},
        "camera": {"look_from": [13, 2, 3], "look_at": [0, 0, 0], "up": [0, 1, 0], "vertical_fov": 30,
                   "aperture": 0.1, "focus_distance": 10},
        "background": SKY,
        "materials": {"glass": {"type": "dielectric", "ior": 1.5}},
        "objects": objects,
    }


# ----------------------------------------------------------------------------------------------------------
# "Ray Tracing: The Next Week", final scene
# ----------------------------------------------------------------------------------------------------------

def book2_final():
    rng = random.Random(2025)
    objects = []
    w = 100
    for i in range(20):
        for j in range(20):
            x0, z0 = -1000 + i * w, -1000 + j * w
            y1 = r6(rng.uniform(1, 101))
            objects.append(box([x0, 0, z0], [x0 + w, y1, z0 + w], "ground"))
    boundary = {"type": "sphere", "center": [360, 150, 145], "radius": 70}
    objects += [
        quad([123, 554, 147], [300, 0, 0], [0, 0, 265], {"type": "diffuse_light", "emission": [7, 7, 7]}),
        {"type": "moving_sphere", "center0": [400, 400, 200], "center1": [430, 400, 200], "radius": 50,
         "material": lambertian([0.7, 0.3, 0.1])},
        sphere([260, 150, 45], 50, "glass"),
        sphere([0, 150, 145], 50, metal([0.8, 0.8, 0.9], 1.0)),
        dict(boundary, material="glass"),
        medium(boundary, 0.2, [0.2, 0.4, 0.9]),
        medium({"type": "sphere", "center": [0, 0, 0], "radius": 5000}, 0.0001, [1, 1, 1]),
        sphere([400, 200, 400], 100,
               {"type": "lambertian", "texture": {"type": "image", "file": "textures/planet-1024x512.png"}}),
        sphere([220, 280, 300], 80,
               {"type": "lambertian", "texture": {"type": "noise", "kind": "marble", "scale": 0.2}}),
    ]
    cluster = {"rotate": [0, 15, 0], "translate": [-100, 270, 395]}
    for _ in range(1000):
        center = [r6(rng.uniform(0, 165)) for _ in range(3)]
        objects.append(sphere(center, 10, "white", transform=cluster))
    return {
        "render": {"width": 800, "height": 800, "samples_per_pixel": 1000, "max_depth": 40},
        "camera": {"look_from": [478, 278, -600], "look_at": [278, 278, 0], "up": [0, 1, 0],
                   "vertical_fov": 40, "aperture": 0},
        "background": BLACK,
        "materials": {
            "ground": lambertian([0.48, 0.83, 0.53]),
            "glass": {"type": "dielectric", "ior": 1.5},
            "white": lambertian([0.73, 0.73, 0.73]),
        },
        "objects": objects,
    }


# ----------------------------------------------------------------------------------------------------------
# Cornell box, and the same room filled with two blocks of smoke
# ----------------------------------------------------------------------------------------------------------

TALL_BOX = ([0, 0, 0], [165, 330, 165], {"rotate": [0, 15, 0], "translate": [265, 0, 295]})
SHORT_BOX = ([0, 0, 0], [165, 165, 165], {"rotate": [0, -18, 0], "translate": [130, 0, 65]})


def cornell_room(light_quad, emission, contents):
    objects = [
        quad([555, 0, 0], [0, 555, 0], [0, 0, 555], "green"),
        quad([0, 0, 0], [0, 555, 0], [0, 0, 555], "red"),
        quad(*light_quad, "light"),
        quad([0, 0, 0], [555, 0, 0], [0, 0, 555], "white"),
        quad([555, 555, 555], [-555, 0, 0], [0, 0, -555], "white"),
        quad([0, 0, 555], [555, 0, 0], [0, 555, 0], "white"),
    ] + contents
    return {
        "render": {"width": 600, "height": 600, "samples_per_pixel": 200, "max_depth": 50},
        "camera": {"look_from": [278, 278, -800], "look_at": [278, 278, 0], "up": [0, 1, 0],
                   "vertical_fov": 40, "aperture": 0},
        "background": BLACK,
        "materials": {
            "red": lambertian([0.65, 0.05, 0.05]),
            "white": lambertian([0.73, 0.73, 0.73]),
            "green": lambertian([0.12, 0.45, 0.15]),
            "light": {"type": "diffuse_light", "emission": emission},
        },
        "objects": objects,
    }


def cornell_box():
    return cornell_room(([343, 554, 332], [-130, 0, 0], [0, 0, -105]), [15, 15, 15],
                        [box(TALL_BOX[0], TALL_BOX[1], "white", TALL_BOX[2]),
                         box(SHORT_BOX[0], SHORT_BOX[1], "white", SHORT_BOX[2])])


def cornell_smoke():
    return cornell_room(([113, 554, 127], [330, 0, 0], [0, 0, 305]), [7, 7, 7],
                        [medium(box(TALL_BOX[0], TALL_BOX[1], transform=TALL_BOX[2]), 0.01, [0, 0, 0]),
                         medium(box(SHORT_BOX[0], SHORT_BOX[1], transform=SHORT_BOX[2]), 0.01, [1, 1, 1])])


# ----------------------------------------------------------------------------------------------------------
# A tiny scene for tests: every object type, material type and texture type, in a 64 x 48 image
# ----------------------------------------------------------------------------------------------------------

def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return [r6(c / n) for c in v]


def tiny():
    objects = [
        sphere([0, -100, 0], 100, "ground"),
        sphere([-1.2, 0.5, 0], 0.5, {"type": "lambertian", "texture": "uv_grid"}),
        sphere([0, 0.5, 0], 0.5, metal([0.8, 0.8, 0.85], 0.1)),
        sphere([1.2, 0.5, 0], 0.5, {"type": "dielectric", "ior": 1.5, "tint": [0.9, 1, 0.9]}),
        sphere([0.6, 1.35, -0.6], 0.15, {"type": "diffuse_light", "emission": [6, 5, 4]}),
        medium({"type": "sphere", "center": [-0.35, 0.3, 1.3], "radius": 0.3}, 2.0, [0.8, 0.8, 0.9]),
        {"type": "moving_sphere", "center0": [0.35, 0.25, 1.3], "center1": [0.35, 0.45, 1.3], "radius": 0.25,
         "time0": 0, "time1": 1,
         "material": {"type": "lambertian", "texture": {"type": "solid", "color": [0.9, 0.5, 0.1]}}},
        quad([-1.8, 0, -1.5], [3.6, 0, 0], [0, 1.8, 0],
             {"type": "lambertian", "texture": {"type": "image", "file": "textures/planet-1024x512.png"}}),
        {"type": "triangle", "vertices": [[0.8, 0, 1.3], [1.5, 0, 1.1], [1.15, 0.8, 1.2]],
         "normals": [unit([-0.3, 0.1, 1]), unit([0.5, 0.1, 1]), unit([0.1, 0.5, 1])],
         "uvs": [[0, 0], [1, 0], [0.5, 1]],
         "material": {"type": "lambertian", "texture": "uv_grid"}},
        box([-0.25, 0, -0.25], [0.25, 0.5, 0.25],
            {"type": "lambertian", "texture": {"type": "noise", "kind": "marble", "scale": 4}},
            {"rotate": [0, 30, 0], "translate": [-1.05, 0, 1.3]}),
    ]
    return {
        "render": {"width": 64, "height": 48, "samples_per_pixel": 16, "max_depth": 8},
        "camera": {"look_from": [0, 1, 4], "look_at": [0, 0.5, 0], "up": [0, 1, 0], "vertical_fov": 45},
        "background": SKY,
        "textures": {
            "checker": {"type": "checker", "odd": [0.2, 0.3, 0.1], "even": [0.9, 0.9, 0.9], "frequency": 10},
            "uv_grid": {"type": "uv_checker", "odd": [0.9, 0.2, 0.2], "even": [0.95, 0.95, 0.95],
                        "columns": 8, "rows": 4},
        },
        "materials": {"ground": {"type": "lambertian", "texture": "checker"}},
        "objects": objects,
    }


# ----------------------------------------------------------------------------------------------------------

def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed-spheres", type=Path,
                        help="the 482 small spheres of the seed's default scene, one per line")
    parser.add_argument("--out", type=Path, default=ROOT / "scenes", help="folder to write the scenes to")
    args = parser.parse_args(argv[1:])

    if args.seed_spheres is not None:
        small = parse_seed_spheres(args.seed_spheres.read_text())
    elif (args.out / "seed-default.json").exists():
        small = spheres_from_existing(args.out / "seed-default.json")
    else:
        parser.error("--seed-spheres is needed the first time (scenes/seed-default.json does not exist yet)")

    scenes = {
        "seed-default.json": seed_default(small),
        "book1-final.json": book1_final(),
        "book2-final.json": book2_final(),
        "cornell-box.json": cornell_box(),
        "cornell-smoke.json": cornell_smoke(),
        "tiny.json": tiny(),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    for name, scene in scenes.items():
        text = dump_scene(scene)
        json.loads(text)  # the output must be valid JSON
        (args.out / name).write_text(text)
        print(f"{args.out / name}: {len(scene['objects'])} objects, {len(text)} bytes")


if __name__ == "__main__":
    main(sys.argv)
