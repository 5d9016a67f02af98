#!/usr/bin/env python3
"""Time to equal error of the light-sampling choices (auto, nee, none) on scenes, side by side in one run.

Each choice renders each scene with two seeds (`--seeds N`: N); for unbiased estimators the spread of the images
about their mean is the variance of one, so the variance needs no reference image. Where a few rare, very bright
samples make most of the variance (caustics found by chance), one pair's estimate scatters widely: take more seeds. The time is the median of `bench` (the
render alone, device events on a GPU), the choices timed in turns over several rounds. Where auto's image equals
another choice's bit for bit, the table says so: their ratio is 1 but for the timing's noise. Efficiency is 1 / (variance x time); the table gives each choice's efficiency
over the better of nee and none, the figure the default must keep near 1 (at least 0.95).

With `--option integrator --choices auto,bdpt --best-of auto` it compares integrators instead: bidirectional path
tracing against the path tracer each device takes by default. A biased estimator (vcm: consistent, its bias shrinking
as samples are added) is measured by its mean squared error against a reference instead of its variance:
`--references DIR` takes DIR/<scene>.pfm, a render of many more samples, and the error of each choice is then the mean
squared difference of its renders from it (the reference's own variance adds to every choice's error alike, so it
needs far more samples than the renders compared).

  bench/light_sampling_efficiency.py PATHTRACER [--scenes a.json,b.json] [--size 400x240] [--spp 64] [--runs 3] [--rounds 3]
                                     [--option light-sampling] [--choices auto,nee,none] [--best-of nee,none] [--seeds 2]
                                     [--references DIR]
                                     [-- extra options for render and bench, e.g. --backend cuda]
"""
import argparse
import filecmp
import os
import re
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tools"))
from compare_pfm import read_pfm  # noqa: E402  (the one PFM reader of the tools)

SHIPPED = ["seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke", "environment", "meshes", "normal-maps", "tiny"]


def run(command):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({result.returncode}):\n{result.stderr}")
    return result.stdout + result.stderr


def variance(paths):
    """The per-value variance of one image, from independent renders (the unbiased sample variance of each value
    across them, averaged over the values; from two renders, half their mean squared difference)."""
    images = [read_pfm(path)[2] for path in paths]
    n = len(images)
    total = 0.0
    for values in zip(*images):
        mean = sum(values) / n
        total += sum((x - mean) ** 2 for x in values) / (n - 1)
    return total / len(images[0])


def squared_error(paths, reference):
    """The mean squared difference of each image from the reference, averaged over the images."""
    target = read_pfm(reference)[2]
    total = 0.0
    for path in paths:
        total += sum((x - y) ** 2 for x, y in zip(read_pfm(path)[2], target)) / len(target)
    return total / len(paths)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("pathtracer")
    parser.add_argument("--scenes", default=",".join(f"scenes/{s}.json" for s in SHIPPED))
    parser.add_argument("--size", default="400x240")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--runs", type=int, default=3, help="bench's runs, of which it gives the median")
    parser.add_argument("--rounds", type=int, default=3, help="turns of timing every choice; the median of the rounds is kept")
    parser.add_argument("--choices", default="auto,nee,none")
    parser.add_argument("--option", default="light-sampling", help="the command-line option whose values are compared")
    parser.add_argument("--best-of", default="nee,none", help="the choices whose best efficiency the others are measured against")
    parser.add_argument("--seeds", type=int, default=2,
                        help="independent renders the variance is estimated from (more where rare bright samples make it scatter)")
    parser.add_argument("--references", help="a folder of <scene>.pfm references: errors against them instead of variances")
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    width, height = args.size.split("x")
    common = ["--width", width, "--height", height, "--spp", str(args.spp)] + extra
    choices, best_of = args.choices.split(","), args.best_of.split(",")
    best_names = ", ".join(best_of)
    measure = "squared error" if args.references else "variance"
    print(f"| scene | {' | '.join(f'{c}: time, {measure}' for c in choices)} | {' | '.join(f'{c} / best of {best_names}' for c in choices)} |")
    print(f"| --- | {' | '.join('---' for _ in choices)} | {' | '.join('---' for _ in choices)} |")
    with tempfile.TemporaryDirectory() as folder:
        for scene in args.scenes.split(","):
            images, variances = {}, {}
            for choice in choices:
                renders = []
                for seed in range(11, 11 + max(args.seeds, 2)):
                    image = os.path.join(folder, f"{choice}-{seed}.pfm")
                    run([args.pathtracer, "render", scene, "--seed", str(seed), f"--{args.option}", choice, "-q", "-o", image] + common)
                    renders.append(image)
                images[choice] = renders[0]
                if args.references:
                    name = os.path.splitext(os.path.basename(scene))[0]
                    variances[choice] = squared_error(renders, os.path.join(args.references, name + ".pfm"))
                else:
                    variances[choice] = variance(renders)
            # The choices timed in turns, so that a machine's changing load falls on all of them alike.
            times = {choice: [] for choice in choices}
            for _ in range(args.rounds):
                for choice in choices:
                    text = run([args.pathtracer, "bench", scene, "--seed", "11", f"--{args.option}", choice, "--runs", str(args.runs)] + common)
                    times[choice].append(float(re.search(r"median of \d+: ([0-9.]+) s", text).group(1)))
            efficiency, cells = {}, []
            for choice in choices:
                seconds, v = statistics.median(times[choice]), variances[choice]
                efficiency[choice] = 1 / (v * seconds) if v > 0 else float("inf")
                same = [other for other in choices if other != choice and filecmp.cmp(images[choice], images[other], shallow=False)]
                cells.append(f"{seconds:.4f} s, {v:.3g}" + (f" (= {', '.join(same)})" if same and choice == "auto" else ""))
            best = max(efficiency.get(c, 0) for c in best_of)
            ratios = [f"{efficiency[c] / best:.2f}" if best > 0 else "-" for c in choices]
            print(f"| {os.path.basename(scene)} | {' | '.join(cells)} | {' | '.join(ratios)} |", flush=True)

if __name__ == "__main__":
    main()
