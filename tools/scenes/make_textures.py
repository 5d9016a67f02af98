"""Draws the image textures of the shipped scenes (designs of our own) as PNG files in scenes/textures/.

Pure Python 3 (standard library only): shapes are rasterised row by row with anti-aliased edges taken from
signed distances, and the result is written by a small PNG encoder (8-bit RGB, zlib level 9).

Usage: python3 tools/scenes/make_textures.py [output-folder]   (default: scenes/textures next to this tree)
"""

import math
import random
import struct
import sys
import time
import zlib
from pathlib import Path


# ----------------------------------------------------------------------------------------------------------
# PNG encoder
# ----------------------------------------------------------------------------------------------------------

# Cost of a filtered byte for the usual "smallest sum of absolute values" choice of the row filter.
_ABS_COST = bytes(min(v, 256 - v) if v else 0 for v in range(256)).replace(b"\x80", b"\x7f")


def _png_chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)


def encode_png(width, height, rows, comment=None):
    """Returns the bytes of an 8-bit RGB PNG; rows are `height` byte strings of 3 * width bytes each."""
    stride = 3 * width
    previous = bytes(stride)
    filtered = bytearray()
    for row in rows:
        assert len(row) == stride
        left = bytes(3) + row[:-3]
        candidates = (
            b"\x00" + row,
            b"\x01" + bytes((a - b) & 255 for a, b in zip(row, left)),
            b"\x02" + bytes((a - b) & 255 for a, b in zip(row, previous)),
            b"\x03" + bytes((a - ((b + c) >> 1)) & 255 for a, b, c in zip(row, left, previous)),
        )
        filtered += min(candidates, key=lambda c: sum(c[1:].translate(_ABS_COST)))
        previous = row
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    text = _png_chunk(b"tEXt", b"Comment\0" + comment.encode("latin-1")) if comment else b""
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + text
            + _png_chunk(b"IDAT", zlib.compress(bytes(filtered), 9)) + _png_chunk(b"IEND", b""))


# ----------------------------------------------------------------------------------------------------------
# Canvas and shapes (coordinates in pixels, y down, pixel centres at +0.5; colours in display sRGB, 0 to 1)
# ----------------------------------------------------------------------------------------------------------

def clamp01(v):
    return 0.0 if v < 0.0 else 1.0 if v > 1.0 else v


def mix(a, b, t):
    return (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t)


def smoothstep(e0, e1, x):
    t = clamp01((x - e0) / (e1 - e0))
    return t * t * (3.0 - 2.0 * t)


def hsv(h, s, v):
    """Colour from hue (turns), saturation and value."""
    h = (h % 1.0) * 6.0
    i = int(h)
    f = h - i
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    return [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i % 6]


class Canvas:
    def __init__(self, width, height):
        self.width, self.height = width, height
        self.r = [0.0] * (width * height)
        self.g = [0.0] * (width * height)
        self.b = [0.0] * (width * height)

    def fill_rows(self, row_colour):
        """Fills the whole canvas; row_colour(y) gives a colour, or three lists of `width` values."""
        w = self.width
        for y in range(self.height):
            c = row_colour(y + 0.5)
            s = y * w
            if isinstance(c[0], (int, float)):
                self.r[s:s + w], self.g[s:s + w], self.b[s:s + w] = [c[0]] * w, [c[1]] * w, [c[2]] * w
            else:
                self.r[s:s + w], self.g[s:s + w], self.b[s:s + w] = c

    def paint(self, shape, colour, opacity=1.0):
        """Composites `shape` over the canvas; colour is a tuple or a function (x, y) -> tuple."""
        w, r, g, b = self.width, self.r, self.g, self.b
        constant = not callable(colour)
        for y in range(max(0, shape.y0), min(self.height, shape.y1)):
            yc = y + 0.5
            span = shape.span(yc)
            if span is None:
                continue
            x0, x1 = max(0, int(span[0])), min(w, int(math.ceil(span[1])))
            row = y * w
            sdf = shape.sdf
            for x in range(x0, x1):
                xc = x + 0.5
                a = 0.5 - sdf(xc, yc)
                if a <= 0.0:
                    continue
                a = opacity if a >= 1.0 else a * opacity
                c = colour if constant else colour(xc, yc)
                i = row + x
                r[i] += (c[0] - r[i]) * a
                g[i] += (c[1] - g[i]) * a
                b[i] += (c[2] - b[i]) * a

    def glow(self, cx, cy, radius, colour, strength, squash=1.0):
        """Adds (strength > 0) or takes away (strength < 0) light with a soft radial falloff."""
        w, r, g, b = self.width, self.r, self.g, self.b
        ry = radius * squash
        for y in range(max(0, int(cy - ry)), min(self.height, int(cy + ry) + 1)):
            dy = (y + 0.5 - cy) / squash
            half = radius * radius - dy * dy
            if half <= 0:
                continue
            half = math.sqrt(half)
            row = y * w
            for x in range(max(0, int(cx - half)), min(w, int(cx + half) + 1)):
                dx = x + 0.5 - cx
                t = 1.0 - (dx * dx + dy * dy) / (radius * radius)
                if t <= 0:
                    continue
                k = strength * t * t
                i = row + x
                if k >= 0:
                    r[i] += colour[0] * k
                    g[i] += colour[1] * k
                    b[i] += colour[2] * k
                else:
                    r[i] *= 1 + k
                    g[i] *= 1 + k
                    b[i] *= 1 + k

    def rows(self):
        w = self.width
        table = [min(255, max(0, int(v * 255.0 + 0.5))) for v in (i / 4096.0 for i in range(4097))]
        out = []
        for y in range(self.height):
            s = y * w
            px = bytearray(3 * w)
            px[0::3] = bytes(table[int(clamp01(v) * 4096.0)] for v in self.r[s:s + w])
            px[1::3] = bytes(table[int(clamp01(v) * 4096.0)] for v in self.g[s:s + w])
            px[2::3] = bytes(table[int(clamp01(v) * 4096.0)] for v in self.b[s:s + w])
            out.append(bytes(px))
        return out

    def save(self, path, comment=None):
        Path(path).write_bytes(encode_png(self.width, self.height, self.rows(), comment))


class Circle:
    def __init__(self, cx, cy, radius):
        self.cx, self.cy, self.radius = cx, cy, radius
        self.y0, self.y1 = int(cy - radius - 2), int(cy + radius + 2)

    def span(self, yc):
        reach = self.radius + 1.5
        dy = yc - self.cy
        if abs(dy) >= reach:
            return None
        half = math.sqrt(reach * reach - dy * dy)
        return self.cx - half, self.cx + half

    def sdf(self, x, y):
        return math.hypot(x - self.cx, y - self.cy) - self.radius


class Ring(Circle):
    def __init__(self, cx, cy, inner, outer):
        super().__init__(cx, cy, outer)
        self.inner = inner

    def sdf(self, x, y):
        d = math.hypot(x - self.cx, y - self.cy)
        return max(d - self.radius, self.inner - d)


class Polygon:
    """Convex polygon; the distance is exact along edges and slightly short near corners (fine for edges)."""

    def __init__(self, points):
        self.points = points
        area = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1]))
        sign = 1.0 if area > 0 else -1.0
        self.edges = []
        for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1]):
            nx, ny = (y1 - y0) * sign, (x0 - x1) * sign  # outward normal
            length = math.hypot(nx, ny)
            nx, ny = nx / length, ny / length
            self.edges.append((nx, ny, -(nx * x0 + ny * y0)))
        self.y0 = int(min(p[1] for p in points) - 2)
        self.y1 = int(max(p[1] for p in points) + 2)

    def span(self, yc):
        lo, hi = yc - 1.5, yc + 1.5
        xs = [x for x, y in self.points if lo <= y <= hi]
        for (x0, y0), (x1, y1) in zip(self.points, self.points[1:] + self.points[:1]):
            for level in (lo, hi):
                if (y0 - level) * (y1 - level) < 0:
                    xs.append(x0 + (x1 - x0) * (level - y0) / (y1 - y0))
        if not xs:
            return None
        return min(xs) - 1.5, max(xs) + 1.5

    def sdf(self, x, y):
        return max(nx * x + ny * y + c for nx, ny, c in self.edges)


def rect(x0, y0, x1, y1, chamfer=0.0):
    if chamfer <= 0:
        return Polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
    c = chamfer
    return Polygon([(x0 + c, y0), (x1 - c, y0), (x1, y0 + c), (x1, y1 - c),
                    (x1 - c, y1), (x0 + c, y1), (x0, y1 - c), (x0, y0 + c)])


def thick_segment(x0, y0, x1, y1, half_width):
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    nx, ny = -dy / length * half_width, dx / length * half_width
    return Polygon([(x0 + nx, y0 + ny), (x1 + nx, y1 + ny), (x1 - nx, y1 - ny), (x0 - nx, y0 - ny)])


class Union:
    def __init__(self, *shapes):
        self.shapes = shapes
        self.y0, self.y1 = min(s.y0 for s in shapes), max(s.y1 for s in shapes)

    def span(self, yc):
        spans = [s for s in (shape.span(yc) for shape in self.shapes) if s is not None]
        if not spans:
            return None
        return min(s[0] for s in spans), max(s[1] for s in spans)

    def sdf(self, x, y):
        return min(s.sdf(x, y) for s in self.shapes)


class Intersection(Union):
    def span(self, yc):
        spans = [shape.span(yc) for shape in self.shapes]
        if any(s is None for s in spans):
            return None
        lo, hi = max(s[0] for s in spans), min(s[1] for s in spans)
        return (lo, hi) if lo < hi else None

    def sdf(self, x, y):
        return max(s.sdf(x, y) for s in self.shapes)


class Difference:
    def __init__(self, shape, hole):
        self.shape, self.hole = shape, hole
        self.y0, self.y1 = shape.y0, shape.y1

    def span(self, yc):
        return self.shape.span(yc)

    def sdf(self, x, y):
        return max(self.shape.sdf(x, y), -self.hole.sdf(x, y))


class Offset:
    """The same shape moved by (dx, dy)."""

    def __init__(self, shape, dx, dy):
        self.shape, self.dx, self.dy = shape, dx, dy
        self.y0, self.y1 = shape.y0 + int(math.floor(dy)), shape.y1 + int(math.ceil(dy))

    def span(self, yc):
        s = self.shape.span(yc - self.dy)
        return None if s is None else (s[0] + self.dx, s[1] + self.dx)

    def sdf(self, x, y):
        return self.shape.sdf(x - self.dx, y - self.dy)


def shaded_sphere(cx, cy, radius, base, light=(-0.55, -0.6, 0.58), shininess=60.0, ambient=0.12):
    """Colour function of a glossy ball lit from `light` (x right, y down, z towards the viewer)."""
    lx, ly, lz = light
    n = math.sqrt(lx * lx + ly * ly + lz * lz)
    lx, ly, lz = lx / n, ly / n, lz / n
    hx, hy, hz = lx, ly, lz + 1.0
    n = math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / n, hy / n, hz / n

    def colour(x, y):
        nx, ny = (x - cx) / radius, (y - cy) / radius
        nz = math.sqrt(max(0.0, 1.0 - nx * nx - ny * ny))
        c = base(nx, ny, nz) if callable(base) else base
        diffuse = max(0.0, nx * lx + ny * ly + nz * lz)
        spec = max(0.0, nx * hx + ny * hy + nz * hz) ** shininess
        rim = (1.0 - nz) ** 3 * 0.35
        k = ambient + (1.0 - ambient) * diffuse
        return (c[0] * k + spec + rim * 0.9, c[1] * k + spec + rim * 0.5, c[2] * k + spec + rim * 0.8)

    return colour


def scatter_stars(canvas, rng, count, y_max, brightness=0.9):
    for _ in range(count):
        x, y = rng.uniform(0, canvas.width), rng.uniform(0, y_max)
        size = rng.choice((0.6, 0.8, 1.0, 1.3))
        tone = rng.uniform(0.4, 1.0) * brightness
        canvas.paint(Circle(x, y, size), (tone, tone, min(1.0, tone * 1.1)))


# ----------------------------------------------------------------------------------------------------------
# Emblem: block letters P T send coloured rays through a lens onto a glossy ball (1024 x 512)
# ----------------------------------------------------------------------------------------------------------

def draw_logo(width=1024, height=512):
    cv = Canvas(width, height)
    top, bottom = (0.03, 0.04, 0.16), (0.22, 0.07, 0.30)
    cv.fill_rows(lambda y: mix(top, bottom, smoothstep(0, height, y)))
    rng = random.Random(7)
    scatter_stars(cv, rng, 160, height)

    mid = height * 0.5
    # Floor: a soft lighter band below the middle, so the ball has somewhere to stand.
    cv.glow(width * 0.5, height * 0.86, width * 0.62, (0.20, 0.12, 0.32), 0.8, squash=0.16)

    # Block letters P and T, 6 units high, with a drop shadow and a vertical gradient.
    unit = 34.0
    lx, ly = 44.0, mid - 3 * unit
    stem = rect(lx, ly, lx + unit * 1.1, ly + 6 * unit, chamfer=6)
    bowl = Difference(rect(lx, ly, lx + 4 * unit, ly + 3.6 * unit, chamfer=unit * 0.9),
                      rect(lx + 1.1 * unit, ly + 1.1 * unit, lx + 2.9 * unit, ly + 2.5 * unit, chamfer=unit * 0.3))
    letter_p = Union(stem, bowl)
    tx = lx + 4.8 * unit
    letter_t = Union(rect(tx, ly, tx + 4 * unit, ly + 1.1 * unit, chamfer=6),
                     rect(tx + 1.45 * unit, ly, tx + 2.55 * unit, ly + 6 * unit, chamfer=6))
    letters_right = tx + 4 * unit

    lens_x, lens_half_height = 560.0, 150.0
    ball_r = 118.0
    ball_x, ball_y = width - 40.0 - ball_r, mid
    focus_x = ball_x - ball_r

    # Rays: parallel from the letters to the lens, then converging on the ball.
    count = 11
    spread = 2.6 * unit
    for k in range(count):
        t = k / (count - 1)
        y = mid - spread + 2 * spread * t
        c = hsv(0.02 + 0.78 * t, 0.75, 1.0)
        for half, alpha in ((7.0, 0.16), (3.2, 0.45), (1.6, 1.0)):
            cv.paint(thick_segment(letters_right + 14, y, lens_x, y, half), c, alpha)
            cv.paint(thick_segment(lens_x, y, focus_x + 4, mid, half), c, alpha)
    # Halo of the focus on the ball.
    cv.glow(focus_x + 10, mid, 60, (1.0, 0.85, 0.6), 0.5)

    for shape in (letter_p, letter_t):
        cv.paint(Offset(shape, 7, 9), (0.0, 0.0, 0.05), 0.6)
    gold_top, gold_bottom = (1.0, 0.86, 0.36), (0.95, 0.38, 0.20)
    for shape in (letter_p, letter_t):
        cv.paint(shape, lambda x, y: mix(gold_top, gold_bottom, smoothstep(ly, ly + 6 * unit, y)))
        # Light edge on the top of each letter.
        cv.paint(Intersection(shape, Offset(Difference(rect(0, 0, width, height), shape), 0, 3)),
                 (1.0, 0.97, 0.85), 0.8)

    # Lens: intersection of two discs, glassy and translucent, with a bright rim and a highlight.
    bulge = 46.0
    big = (lens_half_height ** 2 + bulge ** 2) / (2 * bulge)
    lens = Intersection(Circle(lens_x - bulge + big, mid, big), Circle(lens_x + bulge - big, mid, big))
    cv.paint(lens, lambda x, y: mix((0.55, 0.85, 1.0), (0.25, 0.45, 0.85), smoothstep(mid - 150, mid + 150, y)),
             0.45)
    rim = Difference(lens, Intersection(Circle(lens_x - bulge + big, mid, big - 4),
                                        Circle(lens_x + bulge - big, mid, big - 4)))
    cv.paint(rim, (0.85, 0.97, 1.0), 0.9)
    cv.paint(Intersection(lens, Ring(lens_x + big - 22, mid, big - 14, big - 8)), (1.0, 1.0, 1.0), 0.35)

    # Ball: shadow, then a glossy sphere with a band pattern.
    cv.glow(ball_x + 12, ball_y + ball_r * 0.98, ball_r * 1.15, (0, 0, 0), -0.75, squash=0.18)

    def ball_base(nx, ny, nz):
        # Stripes of latitude around a tilted axis.
        v = 0.8 * ny - 0.35 * nx + 0.45 * nz
        band = 0.5 + 0.5 * math.sin(v * 9.0)
        return mix((0.95, 0.30, 0.42), (1.0, 0.62, 0.18), smoothstep(0.35, 0.65, band))

    cv.paint(Circle(ball_x, ball_y, ball_r), shaded_sphere(ball_x, ball_y, ball_r, ball_base))
    return cv


# ----------------------------------------------------------------------------------------------------------
# Banner: diagonal stripes, ribbons and three ring targets (1280 x 559); it tiles horizontally
# ----------------------------------------------------------------------------------------------------------

def draw_banner(width=1280, height=559):
    cv = Canvas(width, height)
    top, bottom = (0.05, 0.42, 0.48), (0.02, 0.16, 0.30)
    period = 80.0  # divides the width, so the left and right edges meet without a seam
    stripe_light = 0.07

    def row(y):
        base = mix(top, bottom, smoothstep(0, height, y))
        lighter = (base[0] + stripe_light, base[1] + stripe_light, base[2] + stripe_light)
        rs, gs, bs = [], [], []
        for x in range(width):
            p = ((x + 0.5 + y) % period) / period * 2.0  # 0..2: first half light, second half dark
            # Anti-aliased square wave: distance in pixels to the nearest stripe edge.
            d = min(p, abs(1.0 - p), 2.0 - p) * period * 0.5 * math.sqrt(0.5)
            w = clamp01(d + 0.5) if p < 1.0 else 1.0 - clamp01(d + 0.5)  # weight of the light stripe
            c = mix(base, lighter, w)
            rs.append(c[0])
            gs.append(c[1])
            bs.append(c[2])
        return rs, gs, bs

    cv.fill_rows(row)

    # Ribbons along the top and bottom: blocks of colour.
    ribbon = 46.0
    blocks = 32
    bw = width / blocks
    for k in range(blocks):
        c = hsv(0.08 + 0.09 * (k % 6), 0.8, 0.98)
        cv.paint(rect(k * bw + 3, 8, (k + 1) * bw - 3, 8 + ribbon, chamfer=5), c)
        c = hsv(0.55 + 0.07 * ((k + 3) % 6), 0.7, 0.95)
        cv.paint(rect(k * bw + 3, height - 8 - ribbon, (k + 1) * bw - 3, height - 8, chamfer=5), c)

    # Three targets of concentric rings, each with its own palette, with soft shadows.
    palettes = [
        [(1.0, 0.85, 0.25), (0.95, 0.35, 0.20), (0.98, 0.96, 0.90), (0.60, 0.15, 0.45)],
        [(0.35, 0.95, 0.70), (0.10, 0.45, 0.85), (0.98, 0.96, 0.90), (0.95, 0.55, 0.15)],
        [(0.95, 0.45, 0.70), (0.45, 0.20, 0.75), (0.98, 0.96, 0.90), (0.20, 0.70, 0.55)],
    ]
    mid = height * 0.5
    radius = 170.0
    band = radius / 7.0
    for k, palette in enumerate(palettes):
        cx = width * (k + 0.5) / 3.0
        cv.glow(cx + 14, mid + 18, radius * 1.12, (0, 0, 0), -0.55)
        for j in range(7):
            outer = radius - j * band
            cv.paint(Circle(cx, mid, outer), palette[j % len(palette)])
        cv.paint(Ring(cx, mid, radius - 3, radius + 3), (1.0, 1.0, 1.0), 0.85)
        cv.glow(cx - radius * 0.35, mid - radius * 0.4, radius * 0.5, (1, 1, 1), 0.18)
    # Small diamonds between the targets.
    for k in range(4):
        cx = width * k / 3.0
        for dy in (-120, 0, 120):
            s = 16.0 if dy == 0 else 10.0
            pts = [(cx, mid + dy - s), (cx + s, mid + dy), (cx, mid + dy + s), (cx - s, mid + dy)]
            for shift in (0.0, width, -width):  # the diamonds on the edge wrap around
                cv.paint(Polygon([(x + shift, y) for x, y in pts]), (1.0, 0.92, 0.55))
    return cv


# ----------------------------------------------------------------------------------------------------------
# Imaginary planet: equirectangular map (1024 x 512) from 3-D value noise on the unit sphere, fixed seed
# ----------------------------------------------------------------------------------------------------------

class ValueNoise3:
    """Smoothly interpolated random values on the integer lattice, hashed through a permutation table."""

    def __init__(self, seed):
        rng = random.Random(seed)
        perm = list(range(256))
        rng.shuffle(perm)
        self.perm = perm + perm
        self.values = [rng.uniform(-1.0, 1.0) for _ in range(256)]

    def fbm_grid(self, points, octaves, frequency, gain=0.5, lacunarity=2.03):
        """Sum of octaves at every (x, y, z) of `points`; returns a list of values in about [-1, 1]."""
        perm, values = self.perm, self.values
        total = [0.0] * len(points)
        amplitude, norm = 1.0, 0.0
        for octave in range(octaves):
            f = frequency * lacunarity ** octave
            shift = 17.31 * octave  # decorrelates the octaves
            for i, (px, py, pz) in enumerate(points):
                x, y, z = px * f + shift, py * f + shift, pz * f + shift
                xi, yi, zi = math.floor(x), math.floor(y), math.floor(z)
                fx, fy, fz = x - xi, y - yi, z - zi
                u, v, w = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy), fz * fz * (3 - 2 * fz)
                xi &= 255
                yi &= 255
                zi &= 255
                a, b = perm[xi] + yi, perm[xi + 1] + yi
                aa, ab, ba, bb = perm[a] + zi, perm[a + 1] + zi, perm[b] + zi, perm[b + 1] + zi
                c000, c001 = values[perm[aa]], values[perm[aa + 1]]
                c010, c011 = values[perm[ab]], values[perm[ab + 1]]
                c100, c101 = values[perm[ba]], values[perm[ba + 1]]
                c110, c111 = values[perm[bb]], values[perm[bb + 1]]
                x00 = c000 + (c100 - c000) * u
                x01 = c001 + (c101 - c001) * u
                x10 = c010 + (c110 - c010) * u
                x11 = c011 + (c111 - c011) * u
                y0 = x00 + (x10 - x00) * v
                y1 = x01 + (x11 - x01) * v
                total[i] += amplitude * (y0 + (y1 - y0) * w)
            norm += amplitude
            amplitude *= gain
        return [t / norm for t in total]


def sphere_grid(width, height):
    """Unit-sphere points at the pixel centres of an equirectangular grid (row-major, north pole first)."""
    points = []
    for y in range(height):
        lat = math.pi * (0.5 - (y + 0.5) / height)
        cl, sl = math.cos(lat), math.sin(lat)
        for x in range(width):
            lon = 2.0 * math.pi * (x + 0.5) / width
            points.append((cl * math.cos(lon), sl, cl * math.sin(lon)))
    return points


def upsample_wrapped(grid, gw, gh, width, height):
    """Bilinear resampling of a gw x gh map to width x height, wrapping in x and clamping in y."""
    out = [0.0] * (width * height)
    sx, sy = gw / width, gh / height
    cols = []
    for x in range(width):
        fx = (x + 0.5) * sx - 0.5
        x0 = math.floor(fx)
        cols.append((x0 % gw, (x0 + 1) % gw, fx - x0))
    for y in range(height):
        fy = min(max((y + 0.5) * sy - 0.5, 0.0), gh - 1.0)
        y0 = min(int(fy), gh - 2)
        t = fy - y0
        r0, r1 = grid[y0 * gw:(y0 + 1) * gw], grid[(y0 + 1) * gw:(y0 + 2) * gw]
        row = [a + (b - a) * t for a, b in zip(r0, r1)]
        out[y * width:(y + 1) * width] = [row[i0] + (row[i1] - row[i0]) * f for i0, i1, f in cols]
    return out


def draw_planet(width=1024, height=512, seed=1234):
    noise = ValueNoise3(seed)
    # Coarse fields on a quarter-size grid, fine detail on a half-size grid; both resampled to full size.
    cw, ch = width // 4, height // 4
    coarse = sphere_grid(cw, ch)
    elevation = noise.fbm_grid(coarse, 5, 1.6)
    moisture = ValueNoise3(seed + 1).fbm_grid(coarse, 3, 2.2)
    ice_edge = ValueNoise3(seed + 2).fbm_grid(coarse, 3, 3.0)
    fw, fh = width // 2, height // 2
    detail = ValueNoise3(seed + 3).fbm_grid(sphere_grid(fw, fh), 3, 24.0)

    # Sea level: 62 % of the surface is water.
    sea = sorted(elevation)[int(0.62 * len(elevation))]
    high = max(elevation)
    elevation = upsample_wrapped(elevation, cw, ch, width, height)
    moisture = upsample_wrapped(moisture, cw, ch, width, height)
    ice_edge = upsample_wrapped(ice_edge, cw, ch, width, height)
    detail = upsample_wrapped(detail, fw, fh, width, height)
    h = [e + 0.09 * d for e, d in zip(elevation, detail)]

    deep, shallow, coast = (0.02, 0.07, 0.24), (0.06, 0.26, 0.50), (0.16, 0.52, 0.62)
    sand, jungle, grass, steppe = (0.80, 0.74, 0.52), (0.10, 0.34, 0.12), (0.30, 0.50, 0.18), (0.58, 0.56, 0.32)
    desert, rock, snow, tundra = (0.82, 0.62, 0.36), (0.42, 0.34, 0.28), (0.95, 0.96, 0.98), (0.48, 0.50, 0.42)
    ice = (0.90, 0.94, 0.98)

    cv = Canvas(width, height)
    span = high - sea
    for y in range(height):
        lat = abs(90.0 * (1.0 - 2.0 * (y + 0.5) / height))
        row = y * width
        above = max(0, y - 1) * width
        below = min(height - 1, y + 1) * width
        warm = 1.0 - smoothstep(20.0, 60.0, lat)  # 1 at the tropics
        for x in range(width):
            i = row + x
            e = h[i]
            if e < sea:
                depth = (sea - e) / 0.4
                c = mix(coast, shallow, smoothstep(0.0, 0.12, depth))
                c = mix(c, deep, smoothstep(0.15, 1.0, depth))
            else:
                a = (e - sea) / span  # 0 at the coast, 1 on the highest peak
                m = moisture[i]
                wet = mix(grass, jungle, warm * smoothstep(-0.1, 0.3, m))
                dry = mix(steppe, desert, warm)
                c = mix(dry, wet, smoothstep(-0.25, 0.15, m))
                c = mix(c, tundra, smoothstep(45.0, 62.0, lat))
                c = mix(sand, c, smoothstep(0.0, 0.04, a))
                c = mix(c, rock, smoothstep(0.45, 0.7, a))
                c = mix(c, snow, smoothstep(0.78, 0.9, a + lat / 400.0))
                # Relief: light from the north-west, from the slope of the elevation.
                xl, xr = row + (x - 1) % width, row + (x + 1) % width
                slope = (h[xl] - h[xr]) + (h[above + x] - h[below + x])
                k = clamp01(0.9 + 6.0 * slope)
                c = (c[0] * k, c[1] * k, c[2] * k)
            # Polar caps with ragged edges.
            cap = smoothstep(-1.0, 1.0, lat - (71.0 + 22.0 * ice_edge[i] + 6.0 * detail[i]))
            if cap > 0.0:
                k = 0.93 + 0.5 * detail[i]
                c = mix(c, (ice[0] * k, ice[1] * k, ice[2] * min(1.0, k + 0.04)), cap)
            cv.r[i], cv.g[i], cv.b[i] = c
    return cv


# ----------------------------------------------------------------------------------------------------------

IMAGES = [
    ("pathtracer-logo-1024x512.png", draw_logo, "pathtracer emblem"),
    ("pathtracer-banner-1280x559.png", draw_banner, "pathtracer banner"),
    ("planet-1024x512.png", draw_planet, "map of an imaginary planet (equirectangular)"),
]


def main(argv):
    out = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parents[2] / "scenes" / "textures"
    out.mkdir(parents=True, exist_ok=True)
    for name, draw, what in IMAGES:
        start = time.perf_counter()
        draw().save(out / name, f"{what}, drawn by tools/scenes/make_textures.py")
        size = (out / name).stat().st_size
        print(f"{out / name}: {size} bytes, {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main(sys.argv)
