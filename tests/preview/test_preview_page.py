"""The live preview (`pathtracer render --preview`) as a person uses it: its page in a real headless browser.

Debian's chromium, driven through chromedriver by selenium. Each test starts the program, opens the page it
serves and checks what the page shows against images the program writes: the picture after some passes is the
film's tone-mapped pixels (the PNG of a render of that many samples, byte for byte), "Save now" writes the image
and renders on, "Stop" ends the render as an interrupt does, and a render that ends while pages watch leaves them
showing its last picture.
"""
import os
import pathlib
import re
import shutil
import struct
import subprocess
import threading
import time
import zlib

import pytest

PROGRAM = os.environ["PATHTRACER"]
SCENES = pathlib.Path(os.environ["PATHTRACER_SCENES"])
SCENE = str(SCENES / "cornell-box.json")
SIZE = ["--width", "96", "--height", "72"]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"

webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (tools/install-deps.sh installs it)")
from selenium.webdriver.chrome.service import Service as ChromeService  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402


def read_png(path):
    """(width, height, rows of RGB bytes) of an 8-bit RGB or RGBA PNG, every filter type undone."""
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    at, idat, header = 8, b"", None
    while at < len(data):
        (length,) = struct.unpack(">I", data[at:at + 4])
        kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        at += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, header
    channels = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, previous = [], bytearray(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            left = line[i - channels] if i >= channels else 0
            up = previous[i]
            corner = previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + left) & 255
            elif kind == 2:
                line[i] = (line[i] + up) & 255
            elif kind == 3:
                line[i] = (line[i] + (left + up) // 2) & 255
            elif kind == 4:
                p = left + up - corner
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                line[i] = (line[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        rows.append(bytes(line[c] for x in range(width) for c in range(x * channels, x * channels + 3)))
        previous = line
    return width, height, b"".join(rows)


def render_png(tmp_path, samples):
    """The image the program writes for this many samples per pixel."""
    out = tmp_path / f"reference-{samples}.png"
    subprocess.run([PROGRAM, "render", SCENE, *SIZE, "--spp", str(samples), "-q", "-o", str(out)], check=True, timeout=300)
    return read_png(out)


class Render:
    """The program rendering with --preview; its standard error collected as it comes."""

    def __init__(self, tmp_path, *args):
        self.output = tmp_path / "preview.png"
        self.process = subprocess.Popen([PROGRAM, "render", SCENE, *SIZE, "--preview", "0", "-o", str(self.output), *args],
                                        stderr=subprocess.PIPE, text=True)
        self.lines = []
        self.url = None
        found = threading.Event()

        def collect():
            for line in self.process.stderr:
                self.lines.append(line)
                match = re.match(r"preview: (http://127\.0\.0\.1:\d+/)", line)
                if match:
                    self.url = match.group(1)
                    found.set()
            found.set()

        self.reader = threading.Thread(target=collect, daemon=True)
        self.reader.start()
        assert found.wait(60) and self.url, "".join(self.lines)

    def wait(self, timeout=60):
        status = self.process.wait(timeout)
        self.reader.join(10)
        return status

    def stop(self):
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


@pytest.fixture
def browser():
    if not (os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER)):
        pytest.skip("Debian's chromium and chromium-driver are not installed (tools/install-deps.sh installs them)")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=900,700",
                     "--force-color-profile=srgb"):
        options.add_argument(argument)
    driver = webdriver.Chrome(service=ChromeService(executable_path=CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def page_value(driver, name):
    return driver.execute_script(f"return document.body.dataset.{name} || '';")


def wait_for_frames(driver, count, timeout=120):
    WebDriverWait(driver, timeout, poll_frequency=0.1).until(lambda d: int(page_value(d, "framesShown") or 0) >= count)


def shown_picture(driver):
    """(width, height, samples per pixel, RGB bytes) of the picture on the page, read from its canvas."""
    width, height, samples, pixels = driver.execute_script("""
        const canvas = document.getElementById("picture");
        const rgba = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
        const rgb = [];
        for (let i = 0; i < rgba.length; i += 4) rgb.push(rgba[i], rgba[i + 1], rgba[i + 2]);
        return [canvas.width, canvas.height, Number(document.body.dataset.frameSamples), rgb];""")
    return width, height, samples, bytes(pixels)


def click(driver, button):
    driver.find_element(By.ID, button).click()


def test_page_shows_the_films_pixels_saves_and_stops(tmp_path, browser):
    render = Render(tmp_path, "--spp", "1000000")
    try:
        browser.get(render.url)
        wait_for_frames(browser, 2)
        width, height, samples, pixels = shown_picture(browser)
        assert (width, height) == (96, 72)
        assert samples > 0
        assert "samples/s" in browser.find_element(By.ID, "numbers").text
        assert "left" in browser.find_element(By.ID, "numbers").text
        # The picture after `samples` samples is the film's tone-mapped pixels: the image of that many samples.
        assert pixels == render_png(tmp_path, samples)[2], f"the picture of {samples} samples per pixel differs from the film's"
        if os.environ.get("PT_PREVIEW_SCREENSHOT"):
            browser.save_screenshot(os.environ["PT_PREVIEW_SCREENSHOT"])

        # A second page at once, then one that leaves: the first goes on updating.
        first = browser.current_window_handle
        browser.switch_to.new_window("window")
        browser.get(render.url)
        wait_for_frames(browser, 2)
        browser.close()
        browser.switch_to.window(first)
        shown = int(page_value(browser, "framesShown"))
        wait_for_frames(browser, shown + 2)

        # "Save now" writes the image of the samples done and the render goes on.
        click(browser, "save")
        WebDriverWait(browser, 60, poll_frequency=0.1).until(
            lambda d: "saved" in d.find_element(By.ID, "message").text and render.output.exists())
        saved_samples = int(re.search(r"at (\d+) samples per pixel", browser.find_element(By.ID, "message").text).group(1))
        assert read_png(render.output)[2] == render_png(tmp_path, saved_samples)[2]
        assert render.process.poll() is None, "the render went on"

        # "Stop" ends it as an interrupt does: the image of the finished samples is written, the page shows it.
        click(browser, "stop")
        assert render.wait() == 0, "".join(render.lines)
        log = "".join(render.lines)
        assert "stopped by the preview page after" in log, log
        final_samples = int(re.search(r"after (\d+) of 1000000 samples per pixel", log).group(1))
        WebDriverWait(browser, 30, poll_frequency=0.1).until(lambda d: page_value(d, "state") == "stopped")
        WebDriverWait(browser, 30, poll_frequency=0.1).until(lambda d: int(page_value(d, "frameSamples")) == final_samples)
        assert shown_picture(browser)[3] == read_png(render.output)[2], "the page shows the image written"
        WebDriverWait(browser, 30, poll_frequency=0.2).until(lambda d: page_value(d, "connection") == "closed")
        assert "the program has ended" in browser.find_element(By.ID, "message").text
    finally:
        render.stop()


def test_render_that_ends_while_watched_leaves_its_last_picture(tmp_path, browser):
    render = Render(tmp_path, "--spp", "1000000", "--time-limit", "6")
    try:
        browser.get(render.url)
        wait_for_frames(browser, 1)
        assert render.wait(120) == 0, "".join(render.lines)
        log = "".join(render.lines)
        final_samples = int(re.search(r"after (\d+) of 1000000 samples per pixel", log).group(1))
        WebDriverWait(browser, 30, poll_frequency=0.1).until(lambda d: int(page_value(d, "frameSamples") or 0) == final_samples)
        assert shown_picture(browser)[3] == read_png(render.output)[2]
        assert page_value(browser, "state") == "stopped"
        assert "wrote" in browser.find_element(By.ID, "message").text or "ended" in browser.find_element(By.ID, "message").text
    finally:
        render.stop()


def test_preview_options_are_checked(tmp_path):
    result = subprocess.run([PROGRAM, "render", SCENE, "--preview", "70000", "-o", str(tmp_path / "x.png")], capture_output=True, text=True)
    assert result.returncode != 0 and "--preview" in result.stderr, result.stderr
    result = subprocess.run([PROGRAM, "render", SCENE, "--preview", "0", "--preview-address", "203.0.113.7", "-o", str(tmp_path / "x.png")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and "cannot listen on 203.0.113.7" in result.stderr, result.stderr
    assert not (tmp_path / "x.png").exists()
