#!/usr/bin/env python3
# Joins the image quality of each number format (the CSVs of `pathtracer numerics`, docs/numerics/*.csv) with the
# hardware cost of its intersection units (tools/hardware/synth.py's CSV) into a Pareto chart (SVG) and a Markdown
# table: PSNR and visible-error share against 7-series LUTs, flip-flops and DSP48 blocks for one of each unit (box,
# triangle, quad, sphere), so one test of each kind per clock.
#
#   tools/hardware/pareto.py --synthesis docs/hardware/synthesis.csv --numerics docs/numerics --svg docs/hardware/pareto.svg
#
# Quality per format is summarised over the scenes it rendered: the median PSNR and the median share of visibly
# different pixels (docs/numerics.md). --float32 adds the float32 point from a CSV of per-operator costs (unit,
# luts, ffs, dsp48 per operation kind, see docs/hardware.md) times each unit's operation counts.

import argparse
import csv
import statistics
import sys
from pathlib import Path

UNITS = ["box", "triangle", "quad", "sphere"]


def read_quality(folder: Path) -> dict:
    """format -> list of (scene, psnr, visible share) over the scenes where it rendered."""
    quality: dict[str, list] = {}
    for path in sorted(folder.glob("*.csv")):
        with path.open() as f:
            for r in csv.DictReader(f):
                if r.get("status") != "ok" or r["format"] == "double":
                    continue
                psnr = float("inf") if r["psnr_db"] == "inf" else float(r["psnr_db"])
                quality.setdefault(r["format"], []).append((Path(r["scene"]).stem, psnr, float(r["visible_share"])))
    return quality


def read_costs(path: Path) -> dict:
    """format -> summed cost of the four units (only formats where all four were synthesised)."""
    per_format: dict[str, dict] = {}
    with path.open() as f:
        for r in csv.DictReader(f):
            if r.get("status") != "ok":
                continue
            entry = per_format.setdefault(r["format"], {"units": set(), "luts": 0, "ffs": 0, "dsp": 0, "bits": int(r["bits"])})
            entry["units"].add(r["unit"])
            entry["luts"] += int(r["xc7_luts"]) + int(r["xc7_srls"] or 0)
            entry["ffs"] += int(r["xc7_ffs"])
            entry["dsp"] += int(r["xc7_dsp48"])
    return {k: v for k, v in per_format.items() if v["units"] >= set(UNITS)}


def float32_cost(path: Path) -> dict:
    """The four units' cost in float32: each operation's cost from a CSV of published figures (operation: add,
    multiply, divide, sqrt, compare; luts, ffs, dsp48) times the operation counts of the kernels' floating-point
    formulation (every operation rounded: the one units.py builds for 64-bit formats)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from units import build  # noqa: E402
    per_op = {}
    with path.open() as f:
        for r in csv.DictReader(f):
            per_op[r["operation"]] = (float(r["luts"]), float(r["ffs"]), float(r["dsp48"]))
    total = [0.0, 0.0, 0.0]
    for unit in UNITS:
        c = build(unit, 32, 32).costs()
        for op, n in (("add", c.add), ("multiply", c.mul), ("divide", c.div), ("sqrt", c.sqrt), ("compare", c.compare)):
            for k in range(3):
                total[k] += per_op[op][k] * n
    return {"luts": total[0], "ffs": total[1], "dsp": total[2], "bits": 32}


def svg_chart(points: list, float_point: dict | None, title: str) -> str:
    """Two rows (median PSNR, median visible share) by three columns (LUTs, FFs, DSP48)."""
    cw, ch, ml, mt, gap = 300, 220, 60, 50, 70
    width, height = ml + 3 * (cw + gap), mt + 2 * (ch + gap) + 20
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="11">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{ml}" y="22" font-size="14">{title}</text>']
    metrics = [("luts", "7-series LUTs (four units)"), ("ffs", "flip-flops (four units)"), ("dsp", "DSP48E1 (four units)")]
    rows = [("psnr", "median PSNR against double (dB)", False), ("visible", "median visibly different pixels (%)", True)]
    for ri, (qkey, qlabel, lower_better) in enumerate(rows):
        for ci, (ckey, clabel) in enumerate(metrics):
            x0, y0 = ml + ci * (cw + gap), mt + ri * (ch + gap)
            xs = [p[ckey] for p in points] + ([float_point[ckey]] if float_point else [])
            ys = [p[qkey] for p in points]
            xmax = max(xs) * 1.1 if xs else 1
            ymax = (max(ys) if ys else 1) * 1.1 or 1
            if not lower_better:
                ymax = max(ymax, 60)
            sx = lambda v: x0 + v / xmax * cw  # noqa: E731
            sy = lambda v: y0 + ch - min(v, ymax) / ymax * ch  # noqa: E731
            out.append(f'<rect x="{x0}" y="{y0}" width="{cw}" height="{ch}" fill="none" stroke="black"/>')
            for k in range(5):
                gx, gy = x0 + k * cw / 4, y0 + ch - k * ch / 4
                out.append(f'<text x="{gx}" y="{y0 + ch + 14}" text-anchor="middle">{xmax * k / 4:.0f}</text>')
                out.append(f'<text x="{x0 - 4}" y="{gy + 4}" text-anchor="end">{ymax * k / 4:.0f}</text>')
            out.append(f'<text x="{x0 + cw / 2}" y="{y0 + ch + 30}" text-anchor="middle">{clabel}</text>')
            out.append(f'<text x="{x0 - 40}" y="{y0 + ch / 2}" transform="rotate(-90 {x0 - 40} {y0 + ch / 2})" text-anchor="middle">{qlabel}</text>')
            for p in points:
                out.append(f'<circle cx="{sx(p[ckey]):.1f}" cy="{sy(p[qkey]):.1f}" r="4" fill="#1f5fbf"/>')
                out.append(f'<text x="{sx(p[ckey]) + 6:.1f}" y="{sy(p[qkey]) - 4:.1f}">{p["format"]}</text>')
            if float_point:
                fx, fy = sx(float_point[ckey]), sy(float_point[qkey])
                out.append(f'<path d="M{fx - 5:.1f} {fy - 5:.1f} l10 10 m0 -10 l-10 10" stroke="#c00" stroke-width="2"/>')
                out.append(f'<text x="{fx + 6:.1f}" y="{fy + 12:.1f}" fill="#c00">float32 (estimate)</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description="Pareto chart of image quality against hardware cost per number format")
    parser.add_argument("--synthesis", required=True)
    parser.add_argument("--numerics", required=True, help="folder of `pathtracer numerics` CSVs")
    parser.add_argument("--svg", required=True)
    parser.add_argument("--float32", help="CSV of float32 per-operation costs (operation,luts,ffs,dsp48,source)")
    args = parser.parse_args()
    quality = read_quality(Path(args.numerics))
    costs = read_costs(Path(args.synthesis))
    points = []
    for fmt, cost in sorted(costs.items(), key=lambda kv: kv[1]["luts"]):
        q = quality.get(fmt)
        if not q:
            continue
        points.append({"format": fmt, "luts": cost["luts"], "ffs": cost["ffs"], "dsp": cost["dsp"], "bits": cost["bits"],
                       "psnr": statistics.median(min(p, 200.0) for _, p, _ in q), "visible": 100 * statistics.median(v for _, _, v in q),
                       "scenes": len(q)})
    float_point = float32_cost(Path(args.float32)) if args.float32 else None
    if float_point and quality.get("float"):
        float_point["psnr"] = statistics.median(min(p, 200.0) for _, p, _ in quality["float"])
        float_point["visible"] = 100 * statistics.median(v for _, _, v in quality["float"])
    elif float_point:
        float_point = None
    Path(args.svg).write_text(svg_chart(points, float_point, "Intersection units: image quality against 7-series cost per number format"))
    print("| format | bits | LUTs | FFs | DSP48 | median PSNR (dB) | median visible (%) | scenes |")
    print("|---|---|---|---|---|---|---|---|")
    for p in points:
        print(f"| {p['format']} | {p['bits']} | {p['luts']} | {p['ffs']} | {p['dsp']} | {p['psnr']:.1f} | {p['visible']:.2f} | {p['scenes']} |")
    if float_point:
        print(f"| float32 (estimate) | 32 | {float_point['luts']:.0f} | {float_point['ffs']:.0f} | {float_point['dsp']:.0f} | "
              f"{float_point['psnr']:.1f} | {float_point['visible']:.2f} | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
