#!/usr/bin/env python3
"""What the live preview costs a render: the same render with no preview, with the preview and nobody watching, with
a client asking what the page asks (no browser: the program's own cost), with no preview but headless Chromium
open on a blank page (what a browser costs by itself on the same cores), and with the preview's page open in that
Chromium (selenium, as the tests drive it), run in turns; the median samples/s of each.

  bench/preview_cost.py PATHTRACER SCENE [--runs 5] [--size 800x480] [--spp 64] [-- extra render options]

Prints each variant's median samples/s and its ratio to the render without a preview.
"""
import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time


def parse_rate(text):
    match = re.search(r"wrote .*: ([0-9.]+) s, ([0-9.]+) ([kMG]?)samples/s", text)
    if not match:
        raise SystemExit(f"no rate in the program's output:\n{text}")
    scale = {"": 1, "k": 1e3, "M": 1e6, "G": 1e9}[match.group(3)]
    return float(match.group(2)) * scale, float(match.group(1))


def start_browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service as ChromeService
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1000,800"):
        options.add_argument(argument)
    return webdriver.Chrome(service=ChromeService(executable_path="/usr/bin/chromedriver"), options=options)


def poll_like_the_page(url, done):
    """What the page asks for, without a browser: the state four times a second, each new frame once."""
    import json
    import urllib.request
    shown = 0
    while not done.is_set():
        try:
            with urllib.request.urlopen(url + "status") as response:
                frame = json.load(response)["frame"]
            if frame > shown:
                with urllib.request.urlopen(url + "frame.png") as response:
                    response.read()
                shown = frame
        except OSError:
            return
        done.wait(0.25)


def run(program, scene, args, variant, browser, output):
    command = [program, "render", scene, *args, "-o", output]
    if variant not in ("none", "browser idle"):
        command += ["--preview", "0"]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
    lines = []
    done = threading.Event()
    pollers = []

    def collect():
        for line in process.stderr:
            lines.append(line)
            match = re.match(r"preview: (http://\S+)", line)
            if match and variant == "watched":
                browser.get(match.group(1))
            elif match and variant == "polled":
                pollers.append(threading.Thread(target=poll_like_the_page, args=(match.group(1), done)))
                pollers[-1].start()

    reader = threading.Thread(target=collect)
    reader.start()
    process.wait()
    done.set()
    reader.join()
    for poller in pollers:
        poller.join()
    if process.returncode != 0:
        raise SystemExit("".join(lines))
    return parse_rate("".join(lines))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("program")
    parser.add_argument("scene")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--size", default="800x480")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("extra", nargs="*")
    options = parser.parse_args()
    width, height = options.size.split("x")
    args = ["--width", width, "--height", height, "--spp", str(options.spp), *options.extra]
    browser = start_browser()
    rates = {"none": [], "unwatched": [], "polled": [], "browser idle": [], "watched": []}
    try:
        with tempfile.TemporaryDirectory() as folder:
            output = f"{folder}/image.png"
            run(options.program, options.scene, args, "none", browser, output)  # warm-up
            for _ in range(options.runs):
                for variant in rates:
                    rates[variant].append(run(options.program, options.scene, args, variant, browser, output)[0])
                    browser.get("about:blank")
    finally:
        browser.quit()
    base = statistics.median(rates["none"])
    for variant, values in rates.items():
        median = statistics.median(values)
        print(f"{variant:12s} median {median / 1e6:8.3f} Msamples/s  ({median / base:.3f} of no preview; runs: "
              + ", ".join(f"{v / 1e6:.3f}" for v in values) + ")")


if __name__ == "__main__":
    sys.exit(main())
