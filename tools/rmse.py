#!/usr/bin/env python3
"""Root-mean-square error of linear PFM images against a reference, over every channel of every pixel, and the
share of it in the pixels brighter than 1.5 in the reference (an emitter seen directly and its edges).
Usage: tools/rmse.py REFERENCE.pfm IMAGE.pfm [IMAGE.pfm ...]"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_pfm import read_pfm  # noqa: E402  (the one PFM reader of the tools)


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    width, height, reference = read_pfm(sys.argv[1])
    bright = [sum(reference[3 * i:3 * i + 3]) / 3 > 1.5 for i in range(width * height)]
    for path in sys.argv[2:]:
        w, h, image = read_pfm(path)
        if (w, h) != (width, height):
            raise SystemExit(f"{path}: {w}x{h}, the reference is {width}x{height}")
        squared = [sum((image[3 * i + c] - reference[3 * i + c]) ** 2 for c in range(3)) for i in range(w * h)]
        total = sum(squared)
        in_bright = sum(s for s, b in zip(squared, bright) if b)
        print(f"{path}: rmse {math.sqrt(total / (3 * w * h)):.5f}, {100 * in_bright / total if total else 0:.0f}% of the squared error in "
              f"{sum(bright)} bright pixels")


if __name__ == "__main__":
    main()
