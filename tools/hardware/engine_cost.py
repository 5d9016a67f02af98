#!/usr/bin/env python3
# What the traversal engine (src/backends/rtl/traversal_engine.v) costs on 7-series and how fast it might clock:
# its units' rows of docs/hardware/synthesis.csv (tools/hardware/synth.py), its control synthesised with Yosys
# (the units as black boxes), and Yosys's static timing of each unit and of the control (cell delays of the 7-series
# models, no routing: an upper bound on the clock).
#
#   tools/hardware/engine_cost.py --contexts 4,16 [--memory-bits 10] [--timing] [--work DIR]
#
# The control is synthesised for each number of contexts given (its context store grows with them; the 64 of the
# simulated engine take Yosys hours, so the script reports a fit through the points it has); the node and primitive
# memories at 2^memory-bits entries (their block RAM grows with the scene, not with the engine: reported apart).

import argparse
import csv
import json
import re
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synth import count  # noqa: E402
from units import ENGINE_UNITS, build, engine_units  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
ENGINE = ROOT / "src" / "backends" / "rtl" / "traversal_engine.v"
# How many of each unit the engine instantiates (two box units test an inner node's children together).
UNIT_COUNT = {"box": 2}


def yosys(script: str, log: Path, timeout: float) -> None:
    subprocess.run(["yosys", "-q", "-l", str(log), "-p", script], check=True, timeout=timeout, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def stubs(units_text: str) -> str:
    """Each unit as a module of the same ports whose outputs are registered from the XOR of its inputs: the
    control's paths then end in registers, as they do at the real units' first stage, and timing sees them."""
    out = []
    for match in re.finditer(r"module (\w+_unit_q\d+_\d+) \((.*?)\);", units_text, re.S):
        name, ports = match.groups()
        inputs, outputs = [], []
        for line in ports.split(","):
            m = re.match(r"\s*(input|output) wire (signed )?(\[(\d+):0\] )?(\w+)", line)
            if m:
                (inputs if m.group(1) == "input" else outputs).append((m.group(5), int(m.group(4)) + 1 if m.group(4) else 1))
        declare = [f"input wire {f'[{w - 1}:0] ' if w > 1 else ''}{n}" for n, w in inputs]
        declare += [f"output reg {f'[{w - 1}:0] ' if w > 1 else ''}{n}" for n, w in outputs]
        data = " ^ ".join(n for n, _ in inputs if n != "clk")
        body = "".join(f"    {n} <= {data};\n" for n, _ in outputs)
        out.append(f"module {name} ({', '.join(declare)});\n  always @(posedge clk) begin\n{body}  end\nendmodule\n")
    defines = "".join(line + "\n" for line in units_text.splitlines() if line.startswith("`define"))
    return defines + "".join(out)


def latest_arrival(log: Path) -> int | None:
    """The STA pass's latest arrival time in picoseconds, from a Yosys log."""
    times = [int(t) for t in re.findall(r"Latest arrival time in '\S+' is (\d+)", log.read_text())]
    return max(times) if times else None


def control(work: Path, units_file: Path, context_bits: int, memory_bits: int, timing: bool, timeout: float) -> dict:
    """The control's cells (units as black boxes), and with --timing its latest arrival (units as register stubs)."""
    modules = re.findall(r"^module (\w+)", units_file.read_text(), re.M)
    chparam = f"chparam -set CONTEXT_BITS {context_bits} -set NODE_BITS {memory_bits} -set PRIMITIVE_BITS {memory_bits} traversal_engine"
    stat = work / f"control_{context_bits}.stat.json"
    if not stat.exists():
        yosys(f"read_verilog {units_file}; read_verilog {ENGINE}; blackbox {' '.join(modules)}; {chparam}; "
              f"synth_xilinx -family xc7 -top traversal_engine; tee -q -o {stat} stat -json", work / f"control_{context_bits}.log", timeout)
    data = json.loads(stat.read_text())
    cells = (data.get("design") or data["modules"]["\\traversal_engine"])["num_cells_by_type"]
    row = {"contexts": 1 << context_bits, "luts": count(cells, r"\$?LUT[1-6]"), "lutram": count(cells, r"RAM(32|64|128|256).*"),
           "ffs": count(cells, r"FD.*"), "carry4": count(cells, r"CARRY4"), "ramb36": count(cells, r"RAMB36.*"),
           "ramb18": count(cells, r"RAMB18.*"), "arrival_ps": None}
    if timing:
        stub_file = work / "stubs.v"
        stub_file.write_text(stubs(units_file.read_text()))
        log = work / f"control_{context_bits}.sta.log"
        if not log.exists() or latest_arrival(log) is None:
            # Without -abc9: Yosys 0.23's abc9 stops on an assertion in this design; the LUTs then carry the library's delays.
            yosys(f"read_verilog {stub_file}; read_verilog {ENGINE}; {chparam}; synth_xilinx -family xc7 -top traversal_engine; "
                  "read_verilog -lib -specify +/xilinx/cells_sim.v; sta", log, timeout)
        row["arrival_ps"] = latest_arrival(log)
    return row


def unit_timing(work: Path, name: str, integer: int, fraction: int, timeout: float) -> int | None:
    u = build(name, integer, fraction)
    verilog = work / f"{u.module_name}.v"
    verilog.write_text(u.verilog())
    log = work / f"{u.module_name}.sta.log"
    if not log.exists() or latest_arrival(log) is None:
        yosys(f"read_verilog {verilog}; synth_xilinx -family xc7 -abc9 -top {u.module_name}; "
              "read_verilog -lib -specify +/xilinx/cells_sim.v; sta", log, timeout)
    return latest_arrival(log)


def nanoseconds(picoseconds: int | None) -> str:
    return f"{picoseconds / 1000:.2f} ns" if picoseconds else "-"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--format", default="16.16")
    parser.add_argument("--contexts", default="4,16", help="context counts (powers of two) to synthesise the control for")
    parser.add_argument("--memory-bits", type=int, default=10, help="node and primitive memories of 2^bits entries")
    parser.add_argument("--synthesis", default=str(ROOT / "docs" / "hardware" / "synthesis.csv"))
    parser.add_argument("--timing", action="store_true", help="Yosys static timing of every unit and of the control")
    parser.add_argument("--timeout", type=float, default=3600)
    parser.add_argument("--work", default="out/engine-cost")
    args = parser.parse_args()
    integer, fraction = (int(x) for x in args.format.lstrip("q").split("."))
    label = f"q{integer}.{fraction}"
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    units_file = work / f"engine_units_q{integer}_{fraction}.v"
    units_file.write_text(engine_units(integer, fraction))

    with open(args.synthesis) as f:
        rows = {(r["unit"], r["format"]): r for r in csv.DictReader(f)}
    print(f"| part of the engine ({label}) | count | LUTs (+ SRL or LUTRAM) | FFs | DSP48E1 | block RAM | latest arrival (Yosys STA, no routing) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    total = {"luts": 0, "extra": 0, "ffs": 0, "dsp": 0}
    for name in ENGINE_UNITS.values():
        r = rows.get((name, label))
        if r is None or not r["xc7_luts"]:
            print(f"| {name} | missing: run tools/hardware/synth.py --units {name} --formats {args.format} | | | | | |")
            continue
        n = UNIT_COUNT.get(name, 1)
        arrival = unit_timing(work, name, integer, fraction, args.timeout) if args.timing else None
        total["luts"] += n * int(r["xc7_luts"])
        total["extra"] += n * int(r["xc7_srls"])
        total["ffs"] += n * int(r["xc7_ffs"])
        total["dsp"] += n * int(r["xc7_dsp48"])
        print(f"| {name} unit | {n} | {r['xc7_luts']} (+{r['xc7_srls']}) | {r['xc7_ffs']} | {r['xc7_dsp48']} | - | {nanoseconds(arrival)} |")
    print(f"| all units | | {total['luts']} (+{total['extra']}) | {total['ffs']} | {total['dsp']} | - | |")
    for bits in (int(c).bit_length() - 1 for c in args.contexts.split(",")):
        c = control(work, units_file, bits, args.memory_bits, args.timing, args.timeout)
        print(f"| control, {c['contexts']} contexts, memories of {1 << args.memory_bits} entries | 1 | {c['luts']} (+{c['lutram']} LUTRAM) | "
              f"{c['ffs']} | 0 | {c['ramb36']} RAMB36, {c['ramb18']} RAMB18 | {nanoseconds(c['arrival_ps'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
