"""Compares two PFM images rendered from the same scene: prints the mean of each, the RMSE and the largest difference."""
import math
import struct
import sys


def read_pfm(path):
    with open(path, "rb") as f:
        if f.readline().strip() != b"PF":
            raise SystemExit(f"{path}: not an RGB PFM file")
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        endian = "<" if scale < 0 else ">"
        data = struct.unpack(f"{endian}{width * height * 3}f", f.read(width * height * 12))
    return width, height, data


def main():
    wa, ha, a = read_pfm(sys.argv[1])
    wb, hb, b = read_pfm(sys.argv[2])
    if (wa, ha) != (wb, hb):
        raise SystemExit("sizes differ")
    n = len(a)
    diff = [x - y for x, y in zip(a, b)]
    rmse = math.sqrt(sum(d * d for d in diff) / n)
    print(f"{sys.argv[1]} vs {sys.argv[2]}: mean {sum(a) / n:.6f} vs {sum(b) / n:.6f}, rmse {rmse:.6f}, "
          f"max |diff| {max(abs(d) for d in diff):.6f}, identical values {sum(1 for d in diff if d == 0) / n:.1%}")


if __name__ == "__main__":
    main()
