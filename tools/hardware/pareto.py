#!/usr/bin/env python3
# Joins the image quality of each number format (the CSVs of `pathtracer numerics`, docs/numerics/*.csv) with the
# hardware cost of its intersection units (tools/hardware/synth.py's CSV) into a Pareto chart (SVG) and a Markdown
# table: PSNR and visible-error share against 7-series LUTs, flip-flops and DSP48 blocks for one of each unit (box,
# triangle, quad, sphere), so one test of each kind per clock.
#
#   tools/hardware/pareto.py --synthesis docs/hardware/synthesis.csv --numerics docs/numerics --svg docs/hardware/pareto.svg
#
# Quality per format is summarised over the scenes it rendered: the median PSNR and the median share of visibly
# different pixels (docs/numerics.md). The float32 point is the synthesised float32 units (tools/hardware/float32.py,
# format "float32" in the synthesis CSV) with the quality of the renderer's float format, drawn as a red cross.

import argparse
import csv
import statistics
import sys
from pathlib import Path

# The synthesis CSV's name of a format -> the numerics CSVs' name of the same format.
QUALITY_NAME = {"float32": "float"}

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
            if not r.get("status", "").startswith("ok"):  # "ok, iCE40 without ice40_dsp": the 7-series figures stand
                continue
            if r["unit"] not in UNITS:  # the traversal engine's other units (set-up, instances, media) are not counted
                continue
            entry = per_format.setdefault(r["format"], {"units": set(), "luts": 0, "ffs": 0, "dsp": 0, "bits": int(r["bits"])})
            entry["units"].add(r["unit"])
            entry["luts"] += int(r["xc7_luts"]) + int(r["xc7_srls"] or 0)
            entry["ffs"] += int(r["xc7_ffs"])
            entry["dsp"] += int(r["xc7_dsp48"])
    return {k: v for k, v in per_format.items() if v["units"] >= set(UNITS)}


def svg_chart(points: list, title: str) -> str:
    """Two rows (median PSNR, median visible share) by three columns (LUTs, FFs, DSP48); float32 as a red cross."""
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
            xs = [p[ckey] for p in points]
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
                px, py = sx(p[ckey]), sy(p[qkey])
                if p["format"] == "float32":
                    out.append(f'<path d="M{px - 5:.1f} {py - 5:.1f} l10 10 m0 -10 l-10 10" stroke="#c00" stroke-width="2"/>')
                    out.append(f'<text x="{px + 6:.1f}" y="{py + 12:.1f}" fill="#c00">float32</text>')
                else:
                    out.append(f'<circle cx="{px:.1f}" cy="{py:.1f}" r="4" fill="#1f5fbf"/>')
                    out.append(f'<text x="{px + 6:.1f}" y="{py - 4:.1f}">{p["format"]}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description="Pareto chart of image quality against hardware cost per number format")
    parser.add_argument("--synthesis", required=True)
    parser.add_argument("--numerics", required=True, help="folder of `pathtracer numerics` CSVs")
    parser.add_argument("--svg", required=True)
    args = parser.parse_args()
    quality = read_quality(Path(args.numerics))
    costs = read_costs(Path(args.synthesis))
    points = []
    for fmt, cost in sorted(costs.items(), key=lambda kv: kv[1]["luts"]):
        q = quality.get(QUALITY_NAME.get(fmt, fmt))
        if not q:
            continue
        points.append({"format": fmt, "luts": cost["luts"], "ffs": cost["ffs"], "dsp": cost["dsp"], "bits": cost["bits"],
                       "psnr": statistics.median(min(p, 200.0) for _, p, _ in q), "visible": 100 * statistics.median(v for _, _, v in q),
                       "scenes": len(q)})
    Path(args.svg).write_text(svg_chart(points, "Intersection units: image quality against 7-series cost per number format"))
    print("| format | bits | LUTs | FFs | DSP48 | median PSNR (dB) | median visible (%) | scenes |")
    print("|---|---|---|---|---|---|---|---|")
    for p in points:
        print(f"| {p['format']} | {p['bits']} | {p['luts']} | {p['ffs']} | {p['dsp']} | {p['psnr']:.1f} | {p['visible']:.2f} | {p['scenes']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
