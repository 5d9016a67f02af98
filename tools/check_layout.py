#!/usr/bin/env python3
"""Checks the floors of src/: every `#include "folder/..."` must be allowed by the table of docs/architecture.md.

  check_layout.py [SOURCE_ROOT]   # the repository (default: the one this script is in); exit 1 on a violation
  check_layout.py --self-test     # shows that a back include and a cycle in the table are caught
"""
import pathlib
import re
import sys
import tempfile

ROW = re.compile(r"^\| `([a-z_]+)/` \|.*\| ([^|]*) \|\s*$")
FOLDER = re.compile(r"`([a-z_]+)/`")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
SOURCES = (".hpp", ".cpp", ".cu", ".h")


def read_floors(doc: pathlib.Path) -> dict[str, set[str]]:
    """The table of the architecture document: folder -> the folders it may include."""
    floors = {}
    for line in doc.read_text().splitlines():
        match = ROW.match(line)
        if match:
            floors[match.group(1)] = set(FOLDER.findall(match.group(2)))
    if not floors:
        raise SystemExit(f"{doc}: no table of floors found")
    return floors


def find_cycle(floors: dict[str, set[str]]) -> list[str] | None:
    """A cycle among the allowed includes, if the table has one (the floors would then not be floors)."""
    state = {}

    def visit(folder, path):
        state[folder] = "open"
        for lower in sorted(floors.get(folder, ())):
            if state.get(lower) == "open":
                return path + [folder, lower]
            if lower not in state:
                found = visit(lower, path + [folder])
                if found:
                    return found
        state[folder] = "done"
        return None

    for folder in sorted(floors):
        if folder not in state:
            found = visit(folder, [])
            if found:
                return found
    return None


def violations(root: pathlib.Path) -> list[str]:
    doc = root / "docs" / "architecture.md"
    floors = read_floors(doc)
    problems = []
    for folder, lower in sorted(floors.items()):
        for name in sorted(lower - floors.keys()):
            problems.append(f"{doc}: {folder}/ may include {name}/, which is not a floor")
    cycle = find_cycle(floors)
    if cycle:
        problems.append(f"{doc}: the floors include one another in a circle: {' -> '.join(cycle)}")
    src = root / "src"
    for path in sorted(src.rglob("*")):
        if path.suffix not in SOURCES or not path.is_file():
            continue
        folder = path.relative_to(src).parts[0]
        if len(path.relative_to(src).parts) == 1:
            continue  # src/CMakeLists.txt and the like
        if folder not in floors:
            problems.append(f"{path}: src/{folder}/ is not a floor of {doc}")
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            match = INCLUDE.match(line)
            if not match or "/" not in match.group(1):
                continue  # <system> headers, generated ones beside the build
            target = match.group(1).split("/")[0]
            if target != folder and target not in floors[folder]:
                problems.append(f"{path}:{number}: {folder}/ includes {match.group(1)}, but may include only "
                                f"{', '.join(sorted(floors[folder])) or 'its own headers'}")
    return problems


def self_test() -> int:
    with tempfile.TemporaryDirectory() as folder:
        root = pathlib.Path(folder)
        (root / "docs").mkdir()
        (root / "src" / "low").mkdir(parents=True)
        (root / "src" / "high").mkdir(parents=True)
        table = "| folder | holds | may include |\n| --- | --- | --- |\n| `low/` | x | (nothing) |\n| `high/` | y | `low/` |\n"
        (root / "docs" / "architecture.md").write_text(table)
        (root / "src" / "high" / "a.hpp").write_text('#include "low/b.hpp"\n')
        (root / "src" / "low" / "b.hpp").write_text("#include <vector>\n")
        if violations(root):
            print("self-test: a downward include was refused")
            return 1
        (root / "src" / "low" / "b.hpp").write_text('#include "high/a.hpp"\n')
        if len(violations(root)) != 1:
            print("self-test: an upward include was not found")
            return 1
        (root / "src" / "low" / "b.hpp").write_text("\n")
        (root / "docs" / "architecture.md").write_text(table.replace("| (nothing) |", "| `high/` |"))
        if not any("circle" in p for p in violations(root)):
            print("self-test: a cycle in the table was not found")
            return 1
    print("self-test: upward includes and cycles are found, downward includes pass")
    return 0


def main() -> int:
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parent.parent)
    problems = violations(root)
    for problem in problems:
        print(problem)
    if problems:
        return 1
    print(f"{root / 'src'}: every include stands on a lower floor")
    return 0


if __name__ == "__main__":
    sys.exit(main())
