#!/usr/bin/env python3
# The hardware units follow the kernel source: a copy of the kernel with one formula changed (sphere_roots divides
# -(b + root) instead of -b - root) gives other Verilog for the three units that call it and the same for the others;
# and a kernel that uses an operation no hardware operator implements stops the recording with the compiler's error
# instead of making a unit.
#
#   units_follow_kernel.py [--cxx COMPILER]
import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools" / "hardware"))
import units  # noqa: E402

SPHERE_USERS = {"sphere", "moving_sphere", "sphere_crossings"}
FORMAT = (16, 16)  # exact products: the branch of sphere_roots changed below


def verilog(recorded: dict) -> dict:
    return {name: units.build(name, *FORMAT, recorded=recorded).verilog() for name in units.UNITS}


def edited_kernel(work: Path, old: str, new: str) -> Path:
    """A copy of src/ whose kernel/shapes.hpp has the first `old` replaced by `new`."""
    sources = work / "src"
    shutil.copytree(ROOT / "src" / "kernel", sources / "kernel")
    shapes = sources / "kernel" / "shapes.hpp"
    text = shapes.read_text()
    if old not in text:
        raise SystemExit(f"kernel/shapes.hpp no longer has `{old}`: update this test to the kernel's formula")
    shapes.write_text(text.replace(old, new, 1))
    return sources


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cxx", default="")
    args = parser.parse_args()
    failures = []
    before = verilog(units.record_graphs(args.cxx))
    with tempfile.TemporaryDirectory() as work:
        sources = edited_kernel(Path(work), "near = S::exact_quotient(-b - root, a);", "near = S::exact_quotient(-(b + root), a);")
        after = verilog(units.record_graphs(args.cxx, sources))
    for name in units.UNITS:
        changed = before[name] != after[name]
        if changed != (name in SPHERE_USERS):
            failures.append(f"{name}: Verilog {'changed' if changed else 'did not change'} with sphere_roots' formula")
    with tempfile.TemporaryDirectory() as work:
        sources = edited_kernel(Path(work), "near = S::exact_quotient(-b - root, a);", "near = abs(S::exact_quotient(-b - root, a));")
        try:
            units.record_graphs(args.cxx, sources)
            failures.append("a kernel calling abs, which no unit implements, was recorded")
        except subprocess.CalledProcessError:
            pass
    for failure in failures:
        print("FAILED:", failure)
    if not failures:
        print(f"the units follow the kernel: {len(SPHERE_USERS)} of {len(units.UNITS)} changed with sphere_roots; an "
              "operation without hardware was refused")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
