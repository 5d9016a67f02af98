"""Writes the normal-map example: scenes/textures/tiles-normal-256x256.png (a tangent-space normal map of bevelled
tiles with a rivet in each, our own design) and scenes/normal-maps.json, which shows it on a floor and a ball.

Pure Python 3 (standard library only; the PNG encoder of make_textures.py). The map follows glTF's convention: the
bytes are linear data, c = (n + 1) / 2, x along growing u (right), y along growing v (up the image), z out of the
surface. Deterministic.

Usage: python3 tools/scenes/make_normal_maps.py [scenes-folder]   (default: scenes/ next to this tree)
"""

import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_textures import encode_png  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SIZE = 256
TILES = 4  # a side
BEVEL = 0.12  # of a tile's width
GROUT = 0.03
RIVET = 0.16  # radius, of a tile's width


def height(x, y):
    """The height field over [0, 1)^2 in image coordinates (y down), in units of a tile's width."""
    tx, ty = (x * TILES) % 1.0, (y * TILES) % 1.0
    edge = min(tx, 1 - tx, ty, 1 - ty)  # distance to the tile's border
    if edge < GROUT:
        h = 0.0
    elif edge < GROUT + BEVEL:
        h = 0.04 * (edge - GROUT) / BEVEL
    else:
        h = 0.04
    r = math.hypot(tx - 0.5, ty - 0.5)
    if r < RIVET:
        h += 0.06 * math.sqrt(1 - (r / RIVET) ** 2)
    return h


def normal_map():
    """Rows of bytes: the normal of the height field by central differences, per texel centre."""
    step = 1.0 / SIZE
    rows = []
    for j in range(SIZE):
        row = bytearray()
        y = (j + 0.5) * step
        for i in range(SIZE):
            x = (i + 0.5) * step
            # Slopes per unit of the tile width (the map's texture space is TILES tiles wide).
            dhdx = (height(x + step / 2, y) - height(x - step / 2, y)) / (step * TILES)
            dhdy = (height(x, y + step / 2) - height(x, y - step / 2)) / (step * TILES)
            # v grows up the image, against y: dh/dv = -dh/dy.
            nx, ny, nz = -dhdx, dhdy, 1.0
            length = math.sqrt(nx * nx + ny * ny + nz * nz)
            row += bytes(min(255, max(0, round((c / length + 1) * 127.5))) for c in (nx, ny, nz))
        rows.append(bytes(row))
    return rows


SCENE = {
    "render": {"width": 480, "height": 270, "samples_per_pixel": 64, "max_depth": 12},
    "camera": {"look_from": [0, 2.2, 3.8], "look_at": [0, 0.35, 0], "vertical_fov": 40},
    "background": {"type": "sky", "horizon": [0.25, 0.25, 0.3], "zenith": [0.08, 0.1, 0.18]},
    "materials": {
        "tiles": {"type": "metallic_roughness", "base_color": [0.75, 0.72, 0.68], "roughness": 0.45,
                  "normal_map": "textures/tiles-normal-256x256.png"},
        "brass": {"type": "metallic_roughness", "base_color": [0.95, 0.78, 0.45], "metallic": 1, "roughness": 0.3,
                  "normal_map": "textures/tiles-normal-256x256.png", "normal_scale": 1.5},
        "plain": {"type": "metallic_roughness", "base_color": [0.95, 0.78, 0.45], "metallic": 1, "roughness": 0.3},
        "lamp": {"type": "diffuse_light", "emission": [40, 34, 28]},
    },
    "objects": [
        {"type": "quad", "corner": [-2, 0, 2], "u": [4, 0, 0], "v": [0, 0, -4], "material": "tiles"},
        {"type": "sphere", "center": [-0.7, 0.6, 0], "radius": 0.6, "material": "brass"},
        {"type": "sphere", "center": [0.7, 0.6, 0], "radius": 0.6, "material": "plain"},
        {"type": "sphere", "center": [-2.6, 0.9, -0.8], "radius": 0.3, "material": "lamp"},
    ],
}


def main(argv):
    out = Path(argv[1]) if len(argv) > 1 else ROOT / "scenes"
    (out / "textures").mkdir(parents=True, exist_ok=True)
    png = encode_png(SIZE, SIZE, normal_map(), comment="pathtracer normal map: bevelled tiles with rivets (our own)")
    (out / "textures" / "tiles-normal-256x256.png").write_bytes(png)
    (out / "normal-maps.json").write_text(json.dumps(SCENE, indent=2) + "\n")
    print(f"wrote {out / 'textures' / 'tiles-normal-256x256.png'} ({len(png)} bytes) and {out / 'normal-maps.json'}")


if __name__ == "__main__":
    main(sys.argv)
