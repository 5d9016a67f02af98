#!/usr/bin/env python3
# Synthesises the intersection units (tools/hardware/units.py) for FPGA families with Yosys and writes their cost as
# CSV: 7-series (synth_xilinx: LUTs, shift-register LUTs, flip-flops, DSP48E1, CARRY4) and iCE40 (synth_ice40 -dsp:
# LUT4s, flip-flops, SB_MAC16, carries), and where a unit fits an iCE40 (HX8K without DSPs, UP5K with its eight
# MAC16: a 16-bit box unit), its maximum clock after placement and routing by nextpnr-ice40.
#
#   tools/hardware/synth.py --output docs/hardware/synthesis.csv [--units box,triangle] [--formats 16.16,24.8,float32]
#
# Yosys runs one at a time (single-threaded); a unit and format that does not finish within --timeout seconds is
# written with status "timeout". Rows already in the output file are kept and skipped (--redo reruns them), so a long
# run can be resumed.

import argparse
import csv
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from units import UNITS, build, format_label, parse_format  # noqa: E402

FIELDS = ["unit", "format", "bits", "latency", "adds", "multiplies", "divides", "square_roots", "compares",
          "exact_multiplies", "exact_adds",
          "xc7_luts", "xc7_srls", "xc7_ffs", "xc7_dsp48", "xc7_carry4", "xc7_seconds",
          "ice40_luts", "ice40_ffs", "ice40_mac16", "ice40_carries", "ice40_seconds",
          "ice40_device", "ice40_fmax_mhz", "status"]

ICE40_DEVICES = [  # (nextpnr option, LUT4s, MAC16s, package), the first that fits is used
    ("hx8k", 7680, 0, "ct256"),
    ("up5k", 5280, 8, "sg48"),
]


# synth_ice40 -dsp with its `coarse` step written out, less the ice40_dsp pass, which packs the registers and adders
# around a multiplier into its SB_MAC16: Yosys 0.23 crashes in that pass on some units (signal 11 on the Q8.8 quad and
# sphere). The multipliers still map to SB_MAC16; the registers and adders that pass would absorb stay in the fabric,
# so the LUT and flip-flop counts are somewhat pessimistic.
ICE40_UNPACKED = "; ".join([
    "synth_ice40 -dsp -top {top} -run begin:coarse",
    "opt_expr", "opt_clean", "check", "opt -nodffe -nosdff", "fsm", "opt", "wreduce", "peepopt", "opt_clean", "share",
    "techmap -map +/cmp2lut.v -D LUT_WIDTH=4", "opt_expr", "opt_clean", "memory_dff", "wreduce t:$mul",
    "techmap -map +/mul2dsp.v -map +/ice40/dsp_map.v -D DSP_A_MAXWIDTH=16 -D DSP_B_MAXWIDTH=16 -D DSP_A_MINWIDTH=2 "
    "-D DSP_B_MINWIDTH=2 -D DSP_Y_MINWIDTH=11 -D DSP_NAME=$__MUL16X16",
    "select a:mul2dsp", "setattr -unset mul2dsp", "opt_expr -fine", "wreduce", "select -clear",
    "chtype -set $mul t:$__soft_mul", "alumacc", "opt", "memory -nomap", "opt_clean",
    "synth_ice40 -dsp -top {top} -run map_ram:"])


def yosys_stat(verilog: Path, top: str, script: str, timeout: float, json_out: Path | None = None) -> dict:
    """Cell counts of the whole design (submodules counted as often as they are instantiated) after a synthesis
    script (given -top, or with {top} where it goes). A result kept in the work folder from the same Verilog is
    reused."""
    stat = json_out.with_suffix(".stat.json") if json_out else verilog.with_suffix(f".{script.split()[0]}.stat.json")
    if not (stat.exists() and stat.stat().st_mtime > verilog.stat().st_mtime):
        write = f"write_json {json_out}; " if json_out else ""
        script = script.format(top=top) if "{top}" in script else f"{script} -top {top}"
        command = f"read_verilog {verilog}; {script}; {write}tee -q -o {stat} stat -json"
        subprocess.run(["yosys", "-q", "-p", command], check=True, timeout=timeout, stdout=subprocess.DEVNULL)
    data = json.loads(stat.read_text())
    if "design" in data:
        return data["design"].get("num_cells_by_type", {})
    modules = data.get("modules", {})
    module = modules.get(f"\\{top}") or modules.get(top) or {}
    return module.get("num_cells_by_type", {})


def count(cells: dict, pattern: str) -> int:
    return sum(n for name, n in cells.items() if re.fullmatch(pattern, name))


def io_shell(u, module: str) -> str:
    """A wrapper with one word of input and output pins for placement: the operands enter through a shift register
    and the outputs leave XORed into one word, so that no logic is removed and few pins are needed."""
    W = u.W
    n = len(u.inputs)
    lines = [f"module shell (input wire clk, input wire in_valid, input wire [{W - 1}:0] din, output reg [{W - 1}:0] dout, output wire out_valid);",
             f"  reg [{W - 1}:0] operand [0:{n - 1}];",
             "  integer k;",
             "  always @(posedge clk) begin",
             "    operand[0] <= din;",
             f"    for (k = 1; k < {n}; k = k + 1) operand[k] <= operand[k - 1];",
             "  end"]
    wires = []
    for name, v in u.outputs:
        lines.append(f"  wire {'' if v.is_bit else f'[{W - 1}:0] '}{name};")
        wires.append(f"{{{W}{{{name}}}}}" if v.is_bit else name)
    ports = ", ".join([".clk(clk)", ".in_valid(in_valid)"] + [f".{name}(operand[{k}])" for k, (name, _) in enumerate(u.inputs)]
                      + [".out_valid(out_valid)"] + [f".{name}({name})" for name, _ in u.outputs])
    lines.append(f"  {module} unit ({ports});")
    lines.append(f"  always @(posedge clk) dout <= {' ^ '.join(wires)};")
    lines.append("endmodule")
    return "\n".join(lines) + "\n"


def place_and_route(u, verilog: Path, work: Path, device: tuple, timeout: float) -> float | None:
    """Maximum clock in MHz reported by nextpnr-ice40 for the unit inside its pin shell; None if it does not route."""
    option, _, _, package = device
    shell = work / f"{u.module_name}_shell.v"
    shell.write_text(io_shell(u, u.module_name))
    netlist = work / f"{u.module_name}_shell.json"
    dsp = " -dsp" if option == "up5k" else ""
    subprocess.run(["yosys", "-q", "-p", f"read_verilog {verilog} {shell}; synth_ice40{dsp} -top shell -json {netlist}"],
                   check=True, timeout=timeout, stdout=subprocess.DEVNULL)
    report = work / f"{u.module_name}_{option}.report.json"
    result = subprocess.run(["nextpnr-ice40", f"--{option}", "--package", package, "--json", str(netlist), "--pcf-allow-unconstrained",
                             "--freq", "50", "--timing-allow-fail", "--report", str(report), "--quiet"], timeout=timeout, capture_output=True, text=True)
    if result.returncode != 0 or not report.exists():
        return None
    data = json.loads(report.read_text())
    clocks = data.get("fmax", {})
    return min((c["achieved"] for c in clocks.values()), default=None)


def synthesise(name: str, fmt: str, work: Path, timeout: float, pnr: bool, ice40_dsp_limit: int) -> dict:
    integer, fraction = parse_format(fmt)
    u = build(name, integer, fraction)
    c = u.costs()
    row = {"unit": name, "format": format_label(u), "bits": u.W, "latency": u.latency(), "adds": c.add, "multiplies": c.mul,
           "divides": c.div, "square_roots": c.sqrt, "compares": c.compare, "exact_multiplies": c.exact_mul,
           "exact_adds": c.exact_add, "status": "ok"}
    verilog = work / f"{u.module_name}.v"
    text = u.verilog()
    if not verilog.exists() or verilog.read_text() != text:  # unchanged Verilog keeps its synthesis results
        verilog.write_text(text)
    try:
        start = time.monotonic()
        cells = yosys_stat(verilog, u.module_name, "synth_xilinx -family xc7", timeout)
        row.update(xc7_luts=count(cells, r"\$?LUT[1-6]"), xc7_srls=count(cells, r"SRL.*"), xc7_ffs=count(cells, r"FD.*"),
                   xc7_dsp48=count(cells, r"DSP48.*"), xc7_carry4=count(cells, r"CARRY4"), xc7_seconds=round(time.monotonic() - start, 1))
        if row["xc7_dsp48"] > ice40_dsp_limit:
            # Far beyond any iCE40 (UP5K has eight MAC16): not worth a long iCE40 synthesis.
            row["ice40_device"] = f"none (over {ice40_dsp_limit} DSP48)"
            return row
        start = time.monotonic()
        try:
            cells = yosys_stat(verilog, u.module_name, "synth_ice40 -dsp", timeout, work / f"{u.module_name}_ice40.json")
        except subprocess.CalledProcessError as e:
            if e.returncode != -11:
                raise
            cells = yosys_stat(verilog, u.module_name, ICE40_UNPACKED, timeout, work / f"{u.module_name}_ice40_unpacked.json")
            row["status"] = "ok, iCE40 without ice40_dsp"
        row.update(ice40_luts=count(cells, r"SB_LUT4"), ice40_ffs=count(cells, r"SB_DFF.*"), ice40_mac16=count(cells, r"SB_MAC16"),
                   ice40_carries=count(cells, r"SB_CARRY"), ice40_seconds=round(time.monotonic() - start, 1))
    except subprocess.TimeoutExpired:
        row["status"] = "timeout"
        return row
    except subprocess.CalledProcessError as e:
        row["status"] = f"yosys failed ({e.returncode})"
        return row
    row["ice40_device"] = "none"
    if pnr:
        # The first device it fits: HX8K maps multipliers to LUTs (no DSP), UP5K has eight MAC16.
        for device in ICE40_DEVICES:
            option, luts, macs, _ = device
            # HX8K has no DSP: only a unit without multipliers can fit it (a multiplier in LUT4s costs about W^2 of
            # them). UP5K takes up to eight MAC16, one per product of at most 16 by 16 bits.
            if row["ice40_luts"] > luts or row["ice40_mac16"] > macs:
                continue
            try:
                fmax = place_and_route(u, verilog, work, device, timeout)
            except (subprocess.TimeoutExpired, subprocess.CalledProcessError):
                fmax = None
            if fmax is not None:
                row["ice40_device"] = option
                row["ice40_fmax_mhz"] = round(fmax, 1)
                break
    return row


def print_table(path: Path) -> None:
    """The synthesis results as the Markdown table of docs/hardware.md."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    order = {u: k for k, u in enumerate(["box", "triangle", "quad", "sphere"])}
    rows.sort(key=lambda r: (order.get(r["unit"], 9), int(r["bits"]), r["format"]))
    print("| unit | format | clocks | 7-series LUTs (+ SRL) | FFs | DSP48E1 | CARRY4 | iCE40 LUT4 | FFs | SB_MAC16 | iCE40 fit, max clock |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if not r["status"].startswith("ok"):
            luts = f"{r['xc7_luts']} (+{r['xc7_srls']})" if r["xc7_luts"] else "-"
            print(f"| {r['unit']} | {r['format']} | {r['latency']} | {luts} | {r['xc7_ffs'] or '-'} | {r['xc7_dsp48'] or '-'} | "
                  f"{r['xc7_carry4'] or '-'} | iCE40: {r['status']} | | | |")
            continue
        fit = r["ice40_device"] or "-"
        if r.get("ice40_fmax_mhz"):
            fit = f"{fit.upper()}, {r['ice40_fmax_mhz']} MHz"
        elif fit.startswith("none (over"):
            fit = "not synthesised (far too large)"
        elif fit == "none":
            fit = "does not fit"
        if r["status"] != "ok":  # "ok, iCE40 without ice40_dsp"
            fit += " (iCE40 without the ice40_dsp pass: registers and adders not packed into the MAC16)"
        print(f"| {r['unit']} | {r['format']} | {r['latency']} | {r['xc7_luts']} (+{r['xc7_srls']}) | {r['xc7_ffs']} | {r['xc7_dsp48']} | {r['xc7_carry4']} | "
              f"{r['ice40_luts'] or '-'} | {r['ice40_ffs'] or '-'} | {r['ice40_mac16'] or '-'} | {fit} |")


def main() -> int:
    parser = argparse.ArgumentParser(description="Synthesise the intersection units and write their cost as CSV")
    parser.add_argument("--output", required=True)
    parser.add_argument("--units", default=",".join(["box", "triangle", "quad", "sphere"]))
    parser.add_argument("--formats", default="8.8,10.10,12.12,16.16,20.12,24.8,32.32,float32")
    parser.add_argument("--timeout", type=float, default=1800, help="seconds per Yosys or nextpnr run")
    parser.add_argument("--no-place", action="store_true", help="skip nextpnr")
    parser.add_argument("--ice40-dsp-limit", type=int, default=40,
                        help="skip the iCE40 synthesis of units needing more DSP48E1 than this on 7-series")
    parser.add_argument("--redo", action="store_true", help="synthesise again the rows already in the output")
    parser.add_argument("--work", help="keep the netlists here")
    parser.add_argument("--table", action="store_true", help="print the output's rows as a Markdown table and stop")
    args = parser.parse_args()
    output = Path(args.output)
    if args.table:
        print_table(output)
        return 0
    rows = {}
    if output.exists() and not args.redo:
        with output.open() as f:
            for r in csv.DictReader(f):
                rows[(r["unit"], r["format"])] = r
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="pt-synth-"))
    work.mkdir(parents=True, exist_ok=True)
    for fmt in args.formats.split(","):
        for name in args.units.split(","):
            key = (name, "float32" if fmt == "float32" else "q{}.{}".format(*parse_format(fmt)))
            if key in rows and rows[key].get("status", "").startswith("ok"):
                continue
            if name not in UNITS:
                raise SystemExit(f"unknown unit {name}")
            start = time.monotonic()
            rows[key] = synthesise(name, fmt, work, args.timeout, not args.no_place, args.ice40_dsp_limit)
            print(f"{name} {key[1]}: {rows[key].get('status')}, {time.monotonic() - start:.0f} s: "
                  + ", ".join(f"{k}={rows[key].get(k)}" for k in ("xc7_luts", "xc7_ffs", "xc7_dsp48", "ice40_luts", "ice40_mac16",
                                                                    "ice40_device", "ice40_fmax_mhz")), flush=True)
            output.parent.mkdir(parents=True, exist_ok=True)
            with output.open("w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=FIELDS)
                writer.writeheader()
                for r in rows.values():
                    writer.writerow({k: r.get(k, "") for k in FIELDS})
    return 0


if __name__ == "__main__":
    sys.exit(main())
