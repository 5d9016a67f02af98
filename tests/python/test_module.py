"""The Python module as a user drives it: the same images and messages as the program, scenes from dicts, settings,
devices, progress that can stop a render, and images written. Run by CTest (tests/CMakeLists.txt), which gives
PYTHONPATH (the built module), PATHTRACER (the program) and PATHTRACER_SCENES (scenes/)."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pathtracer

PROGRAM = str(Path(os.environ["PATHTRACER"]).resolve())
SCENES = Path(os.environ["PATHTRACER_SCENES"]).resolve()
SMALL = dict(width=40, height=24, spp=4)


def program_render(tmp_path, scene, *args):
    """The program's image of `scene` as a float32 array, through a PFM file (exact floats)."""
    out = tmp_path / "program.pfm"
    subprocess.run([PROGRAM, "render", str(scene), "-q", "-o", str(out), *args], check=True)
    return read_pfm(out)


def read_pfm(path):
    data = Path(path).read_bytes()
    header = data.split(b"\n", 3)
    assert header[0] == b"PF"
    width, height = map(int, header[1].split())
    scale = float(header[2])
    pixels = np.frombuffer(header[3], dtype="<f4" if scale < 0 else ">f4").reshape(height, width, 3)
    return pixels[::-1]  # PFM stores rows from the bottom


def program_error(tmp_path, *args):
    """The line the program prints for an error, after 'pathtracer: error: '."""
    run = subprocess.run([PROGRAM, "render", *args, "-q", "-o", str(tmp_path / "x.png")], capture_output=True, text=True)
    assert run.returncode == 1
    line = run.stderr.strip()
    assert line.startswith("pathtracer: error: ") and "\n" not in line
    return line[len("pathtracer: error: "):]


@pytest.mark.parametrize("scene", ["cornell-box.json", "seed-default.json", "meshes.json"])
def test_render_is_the_programs_image_bit_for_bit(tmp_path, scene):
    render = pathtracer.render(SCENES / scene, **SMALL)
    assert isinstance(render.image, np.ndarray)
    assert render.image.dtype == np.float32 and render.image.shape == (24, 40, 3)
    expected = program_render(tmp_path, SCENES / scene, "--width", "40", "--height", "24", "--spp", "4")
    assert np.array_equal(render.image, expected)
    assert np.array_equal(np.asarray(render), render.image)
    assert render.samples_per_pixel == 4 and not render.stopped_early
    assert render.samples == 40 * 24 * 4 and render.rays >= render.samples


def test_every_setting_reaches_the_render(tmp_path):
    scene = SCENES / "cornell-box.json"
    args = dict(width=32, height=20, spp=3, depth=4, seed=7, light_sampling="none", sampler="independent", integrator="wavefront",
                number_format="double", threads=1)
    render = pathtracer.render(scene, **args)
    expected = program_render(tmp_path, scene, "--width", "32", "--height", "20", "--spp", "3", "--depth", "4", "--seed", "7",
                              "--light-sampling", "none", "--sampler", "independent", "--integrator", "wavefront", "--number-format",
                              "double", "--threads", "1")
    assert np.array_equal(render.image, expected)
    # Each of them changes the image.
    for name, value in [("depth", 2), ("seed", 8), ("light_sampling", "nee"), ("sampler", "sobol"), ("number_format", "float")]:
        changed = pathtracer.render(scene, **{**args, name: value})
        assert not np.array_equal(changed.image, render.image), name
    # The light threshold, where there are shadow rays to leave out.
    lit = {**args, "light_sampling": "auto"}
    faint = pathtracer.render(scene, **lit, light_threshold=0.5)
    assert not np.array_equal(faint.image, pathtracer.render(scene, **lit).image)
    assert np.array_equal(faint.image, program_render(tmp_path, scene, "--width", "32", "--height", "20", "--spp", "3", "--depth", "4", "--seed",
                                                      "7", "--light-sampling", "auto", "--light-threshold", "0.5", "--sampler",
                                                      "independent", "--integrator", "wavefront", "--number-format", "double", "--threads",
                                                      "1"))


def test_threads_and_integrators_give_one_image():
    scene = SCENES / "seed-default.json"
    images = [pathtracer.render(scene, **SMALL, threads=t, integrator=i).image for t in (1, 2) for i in ("megakernel", "wavefront")]
    for image in images[1:]:
        assert np.array_equal(image, images[0])


def test_bdpt_is_the_programs_image_bit_for_bit_on_any_thread_count(tmp_path):
    scene = SCENES / "caustics.json"
    images = [pathtracer.render(scene, **SMALL, threads=t, integrator="bdpt").image for t in (1, 2)]
    assert np.array_equal(images[0], images[1])
    expected = program_render(tmp_path, scene, "--width", "40", "--height", "24", "--spp", "4", "--integrator", "bdpt")
    assert np.array_equal(images[0], expected)
    # Fixed point too (docs/numerics.md): Q32.32 follows double.
    fixed = pathtracer.render(scene, **SMALL, integrator="bdpt", number_format="q32.32").image
    double = pathtracer.render(scene, **SMALL, integrator="bdpt", number_format="double").image
    assert abs(fixed.mean() - double.mean()) < 1e-3 * double.mean()


def test_vcm_is_the_programs_image_bit_for_bit_with_its_radius(tmp_path):
    scene = SCENES / "caustics.json"
    images = [pathtracer.render(scene, **SMALL, threads=t, integrator="vcm", merge_radius=0.05).image for t in (1, 2)]
    assert np.array_equal(images[0], images[1])
    expected = program_render(tmp_path, scene, "--width", "40", "--height", "24", "--spp", "4", "--integrator", "vcm", "--merge-radius", "0.05")
    assert np.array_equal(images[0], expected)
    # The radius reaches the render, and the default is the program's too.
    assert not np.array_equal(pathtracer.render(scene, **SMALL, integrator="vcm").image, images[0])
    assert np.array_equal(pathtracer.render(scene, **SMALL, integrator="vcm").image,
                          program_render(tmp_path, scene, "--width", "40", "--height", "24", "--spp", "4", "--integrator", "vcm"))
    with pytest.raises(pathtracer.Error, match="^merge_radius=-1"):
        pathtracer.render(scene, **SMALL, integrator="vcm", merge_radius=-1)


def test_fixed_point_formats_render():
    formats = pathtracer.number_formats()
    assert {"float", "double", "q16.16"} <= set(formats)
    double = pathtracer.render(SCENES / "cornell-box.json", **SMALL, number_format="double").image
    fixed = pathtracer.render(SCENES / "cornell-box.json", **SMALL, number_format="q16.16").image
    assert np.isfinite(fixed).all()
    assert abs(fixed.mean() - double.mean()) < 0.05 * double.mean()


def test_a_dict_renders_as_its_file_does(monkeypatch):
    path = SCENES / "cornell-box.json"
    description = json.loads(path.read_text())
    from_dict = pathtracer.Scene.from_dict(description, base_folder=str(SCENES))
    assert from_dict.settings == pathtracer.Scene(path).settings
    assert np.array_equal(pathtracer.render(from_dict, **SMALL).image, pathtracer.render(path, **SMALL).image)
    # A dict given to render directly: paths relative to the working folder.
    monkeypatch.chdir(SCENES)
    assert np.array_equal(pathtracer.render(description, **SMALL).image, pathtracer.render(path, **SMALL).image)


def test_scene_settings_and_overrides():
    scene = pathtracer.Scene(SCENES / "seed-default.json")
    settings = scene.settings
    assert set(settings) == {"width", "height", "spp", "depth", "seed", "light_sampling", "light_threshold", "sampler", "noise_threshold"}
    assert settings["light_sampling"] == "auto" and settings["light_threshold"] == 0.01
    render = pathtracer.render(scene, width=16, spp=1)
    assert render.image.shape == (settings["height"], 16, 3)
    assert scene.source.endswith("seed-default.json")
    assert "seed-default.json" in repr(scene)


def test_noise_threshold_gives_the_programs_adaptive_image(tmp_path):
    scene = SCENES / "tiny.json"
    render = pathtracer.render(scene, width=40, height=24, spp=64, noise_threshold=0.03, layers="samples")
    expected = program_render(tmp_path, scene, "--width", "40", "--height", "24", "--spp", "64", "--noise-threshold", "0.03")
    assert np.array_equal(render.image, expected)
    samples = render.layers["samples"]
    assert samples.min() == 16 and samples.max() == 64  # the sky stopped at the first judgement, noisy pixels went on
    assert render.samples == int(samples.sum()) < 40 * 24 * 64
    with pytest.raises(pathtracer.Error, match=r"^noise_threshold=-1: not an error in 0\.\.1"):
        pathtracer.render(scene, **SMALL, noise_threshold=-1)


def test_errors_carry_the_programs_message(tmp_path):
    broken = tmp_path / "broken.json"
    broken.write_text('{"camera": {"look_from": [0, 0, 1], "look_at": [0, 0, 0], "vertical_fov": 40},\n "objects": [{"type": "sphere", "radius": -1}]}')
    expected = program_error(tmp_path, str(broken))
    with pytest.raises(pathtracer.Error) as raised:
        pathtracer.render(broken)
    assert str(raised.value) == expected
    with pytest.raises(pathtracer.Error) as raised:
        pathtracer.Scene(tmp_path / "missing.json")
    assert str(raised.value) == program_error(tmp_path, str(tmp_path / "missing.json"))
    # Out-of-range settings are named as Python spells them.
    with pytest.raises(pathtracer.Error, match=r"^spp=0: not in 1\.\.1048576$"):
        pathtracer.render(SCENES / "tiny.json", spp=0)
    with pytest.raises(pathtracer.Error, match="^width=9000 height=9000: 9000x9000 pixels is too large"):
        pathtracer.render(SCENES / "tiny.json", width=9000, height=9000)
    for bad in [dict(backend="vulkan"), dict(integrator="fast"), dict(number_format="half"), dict(light_sampling="all"), dict(sampler="grid"),
                dict(light_threshold=-0.5), dict(light_threshold=float("nan")),
                dict(time_limit=float("nan")), dict(device="7"), dict(sycl_device=0)]:
        with pytest.raises(pathtracer.Error):
            pathtracer.render(SCENES / "tiny.json", **SMALL, **bad)
    # A dict's bad value is named by its JSON path.
    description = json.loads((SCENES / "tiny.json").read_text())
    description["camera"]["vertical_fov"] = "wide"
    with pytest.raises(pathtracer.Error, match="/camera/vertical_fov"):
        pathtracer.Scene.from_dict(description, base_folder=str(SCENES))
    with pytest.raises(TypeError):
        pathtracer.render(42)


def test_progress_reports_every_pass_and_can_stop_the_render():
    reports = []
    full = pathtracer.render(SCENES / "cornell-box.json", width=32, height=20, spp=64, progress=reports.append)
    assert reports and reports[-1]["samples_done"] == 64 and reports[-1]["samples_total"] == 64
    assert all(r["samples_done"] <= 64 for r in reports)

    def stop_after_first(report):
        return False

    stopped = pathtracer.render(SCENES / "cornell-box.json", width=32, height=20, spp=100000, progress=stop_after_first)
    assert stopped.stopped_early and 0 < stopped.samples_per_pixel < 100000
    assert np.isfinite(stopped.image).all() and stopped.image.mean() > 0
    assert full.samples_per_pixel == 64 and not full.stopped_early


def test_an_exception_in_the_progress_callback_stops_the_render_and_is_raised():
    def fail(report):
        raise ValueError("seen enough")

    with pytest.raises(ValueError, match="seen enough"):
        pathtracer.render(SCENES / "cornell-box.json", width=32, height=20, spp=100000, progress=fail)


def test_time_limit_stops_the_render():
    render = pathtracer.render(SCENES / "cornell-box.json", width=32, height=20, spp=1000000, time_limit=0.3)
    assert render.stopped_early and render.samples_per_pixel < 1000000


def test_devices_and_backends():
    devices = pathtracer.devices()
    assert devices[0]["backend"] == "cpu" and devices[0]["index"] == 0 and "hardware threads" in devices[0]["name"]
    assert all(d["index"] >= 0 for d in devices)
    listed = subprocess.run([PROGRAM, "devices"], capture_output=True, text=True, check=True).stdout
    for d in devices[1:]:
        assert f"{d['backend']} {d['index']}: {d['name']}" in listed
    assert "cpu" in pathtracer.backends()
    assert pathtracer.__version__ in subprocess.run([PROGRAM, "--version"], capture_output=True, text=True, check=True).stdout


def test_write_image_writes_what_the_program_writes(tmp_path):
    scene = SCENES / "cornell-box.json"
    render = pathtracer.render(scene, **SMALL)
    for extension in ("png", "pfm", "exr"):
        ours = tmp_path / f"ours.{extension}"
        pathtracer.write_image(ours, render.image)
        theirs = tmp_path / f"theirs.{extension}"
        subprocess.run([PROGRAM, "render", str(scene), "-q", "-o", str(theirs), "--width", "40", "--height", "24", "--spp", "4"], check=True)
        assert ours.read_bytes() == theirs.read_bytes(), extension
    with pytest.raises(pathtracer.Error, match="shape"):
        pathtracer.write_image(tmp_path / "flat.png", np.zeros((4, 4)))
    with pytest.raises(pathtracer.Error):
        pathtracer.write_image(tmp_path / "image.bmp", render.image)


def test_the_dict_of_docs_python_md_renders():
    description = {
        "camera": {"look_from": [0, 1, 4], "look_at": [0, 0.5, 0], "vertical_fov": 40},
        "render": {"width": 160, "height": 90, "samples_per_pixel": 16},
        "objects": [
            {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": {"type": "lambertian", "albedo": [0.8, 0.3, 0.2]}},
            {"type": "sphere", "center": [0, -1000, 0], "radius": 1000, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        ],
    }
    scene = pathtracer.Scene.from_dict(description)
    assert scene.settings["width"] == 160 and scene.settings["spp"] == 16
    image = pathtracer.render(scene, number_format="q16.16", spp=2).image
    assert image.shape == (90, 160, 3) and np.isfinite(image).all()
    # The sphere is reddish where the camera looks at it.
    centre = image[40:50, 75:85].mean(axis=(0, 1))
    assert centre[0] > centre[2]


def test_layers_come_as_arrays_and_match_the_exr_the_program_writes(tmp_path):
    scene = SCENES / "tiny.json"
    render = pathtracer.render(scene, **SMALL, layers="all")
    assert set(render.layers) == {"albedo", "normal", "depth", "samples"}
    assert render.layers["albedo"].shape == (24, 40, 3) and render.layers["normal"].shape == (24, 40, 3)
    assert render.layers["depth"].shape == (24, 40) and render.layers["samples"].shape == (24, 40)
    assert (render.layers["samples"] == 4).all()
    assert ((render.layers["albedo"] >= 0) & (render.layers["albedo"] <= 1)).all()
    lengths = np.linalg.norm(render.layers["normal"], axis=2)
    assert (lengths <= 1 + 1e-5).all() and (lengths > 0.5).any()
    assert np.array_equal(render.image, pathtracer.render(scene, **SMALL).image)  # layers leave the image as it is
    only = pathtracer.render(scene, **SMALL, layers=["depth"])
    assert set(only.layers) == {"depth"} and np.array_equal(only.layers["depth"], render.layers["depth"])
    assert pathtracer.render(scene, **SMALL).layers == {}
    with pytest.raises(pathtracer.Error, match="^layers='nrm': no layer 'nrm' \\(layers: albedo, normal, depth, samples, or all\\)$"):
        pathtracer.render(scene, **SMALL, layers="nrm")
