// The Python module `pathtracer`: scenes from files or dicts, renders on any backend and device into NumPy arrays,
// with a progress callback that can stop them; the same loading, settings, backends and render loop as the program.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <fmt/format.h>

#include "app/render_overrides.hpp"
#include "backends/registry.hpp"
#include "base/errors.hpp"
#include "base/number_formats.hpp"
#include "film/film.hpp"
#include "film/layers.hpp"
#include "image/image_io.hpp"
#include "loading/scene_loader.hpp"

#ifndef PT_VERSION
#define PT_VERSION "0.0.0"
#endif

namespace py = pybind11;

namespace pt {
namespace {

// A parsed scene, shared by the renders made of it (each flattens it for its own number format).
struct PyScene {
  std::shared_ptr<const SceneDescription> scene;
};

const OverrideSpelling kPythonSpelling{"width=", "height=", "spp=", "depth=", "noise_threshold=", "light_threshold=", ""};

py::dict settings_dict(const RenderSettings& settings) {
  py::dict d;
  d["width"] = settings.width;
  d["height"] = settings.height;
  d["spp"] = settings.samples_per_pixel;
  d["depth"] = settings.max_depth;
  d["seed"] = settings.seed;
  d["light_sampling"] = light_sampling_name(settings.light_sampling);
  d["sampler"] = sampler_name(settings.sampler);
  d["noise_threshold"] = settings.noise_threshold;
  d["light_threshold"] = settings.light_threshold;
  return d;
}

PyScene load_scene(const std::string& path, bool trust_model_paths) {
  return PyScene{std::make_shared<const SceneDescription>(load_scene_file(path, model_references(trust_model_paths)))};
}

// A dict in the scene file's format, read as the file would be: through its JSON text, so that every check and
// message is the file's (values named by their JSON path); image and model paths are relative to `base_folder`.
PyScene scene_from_dict(const py::dict& description, const std::string& base_folder, bool trust_model_paths) {
  const std::string text = py::module_::import("json").attr("dumps")(description, py::arg("indent") = 1).cast<std::string>();
  return PyScene{std::make_shared<const SceneDescription>(
      parse_scene(text, "scene dict", std::filesystem::path(base_folder), model_references(trust_model_paths)))};
}

// What a render returns: the image as float32 (height, width, 3), linear RGB, rows from the top; and how it went.
struct PyRender {
  py::array_t<float> image;
  u32 samples_per_pixel = 0;  // done: all asked for, or fewer where the render was stopped
  bool stopped_early = false;
  double seconds = 0;
  u64 samples = 0, rays = 0, dropped_samples = 0;
  std::string backend;
  py::dict layers;  // name -> float32 array: (height, width, 3) for albedo and normal, (height, width) for depth and samples
};

struct RenderArguments {
  RenderOverrides overrides;
  std::string backend = "cpu", device = "0", integrator = "auto", number_format = "float";
  unsigned threads = 0;
  int sycl_device = -1;
  double time_limit = 0;
  py::object progress = py::none();
  std::vector<std::string> layers;
  double merge_radius = 0;  // integrator vcm's first radius; 0: from the camera
};

Integrator integrator_named(const std::string& name) {
  if (name == "wavefront") return Integrator::kWavefront;
  if (name == "megakernel") return Integrator::kMegakernel;
  if (name == "auto") return Integrator::kAuto;
  if (name == "bdpt") return Integrator::kBidirectional;
  if (name == "vcm") return Integrator::kVertexMerging;
  throw InputError(fmt::format("integrator='{}': not one of auto, megakernel, wavefront, bdpt, vcm", name));
}

template <class T>
PyRender render_with(const SceneDescription& scene, const RenderArguments& arguments) {
  RenderSettings settings = apply_overrides(scene, arguments.overrides, kPythonSpelling);
  settings.merge_radius = arguments.merge_radius;
  const std::vector<std::string> backends = backend_names();
  if (std::ranges::find(backends, arguments.backend) == backends.end())
    throw InputError(fmt::format("backend='{}': not one of {}", arguments.backend, backend_choices()));
  if (arguments.sycl_device >= 0 && arguments.backend != "sycl")
    throw InputError(fmt::format("sycl_device={}: only backend='sycl' takes it", arguments.sycl_device));
  const Integrator integrator = integrator_named(arguments.integrator);
  const DeviceList devices = parse_device_list(arguments.device, arguments.backend);

  // The callback runs between passes with the interpreter's lock; a stop it asks for (False returned, an exception
  // raised, Ctrl-C) is a flag that the render loop and the backends' threads read without it.
  std::atomic<bool> stop{false};
  std::exception_ptr raised;
  const ProgressCallback progress = [&](const Progress& p) {
    const py::gil_scoped_acquire gil;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (arguments.progress.is_none()) return;
      py::dict report;
      report["samples_done"] = p.samples_done;
      report["samples_total"] = p.samples_total;
      report["elapsed_seconds"] = p.elapsed_seconds;
      report["samples_per_second"] = p.samples_per_second;
      const py::object answer = arguments.progress(report);
      if (!answer.is_none() && !answer.cast<bool>()) stop = true;
    } catch (...) {
      if (!raised) raised = std::current_exception();
      stop = true;
    }
  };
  RenderControl control;
  control.stop_requested = [&] { return stop.load(); };
  control.time_limit_seconds = arguments.time_limit;

  PyRender result;
  LinearImage image;
  RenderLayers layers;
  {
    const py::gil_scoped_release released;
    const FlatScene<T> flat = flatten_scene<T>(scene, settings);
    const std::unique_ptr<RenderBackend<T>> backend =
        make_render_backend<T>(arguments.backend, devices, arguments.threads, integrator, arguments.sycl_device);
    const RenderedFilm film = render_film(*backend, flat, progress, control);
    image = resolve_film(film.pixels(), film.width, film.height);
    if (!arguments.layers.empty() && !raised) layers = render_layers(*backend, flat, film, arguments.layers);
    result.samples_per_pixel = film.samples_done;
    result.stopped_early = film.stopped_early;
    result.seconds = film.stats.seconds;
    result.samples = film.stats.samples;
    result.rays = film.stats.rays;
    result.dropped_samples = film.stats.dropped_samples;
    result.backend = backend->name();
  }
  if (raised) std::rethrow_exception(raised);
  result.image = py::array_t<float>({static_cast<py::ssize_t>(image.height), static_cast<py::ssize_t>(image.width), py::ssize_t{3}});
  std::memcpy(result.image.mutable_data(), image.rgb.data(), image.rgb.size() * sizeof(float));
  const auto height = static_cast<py::ssize_t>(image.height), width = static_cast<py::ssize_t>(image.width);
  for (const std::string& name : arguments.layers) {
    const bool colour = name == "albedo" || name == "normal";
    py::array_t<float> array = colour ? py::array_t<float>({height, width, py::ssize_t{3}}) : py::array_t<float>({height, width});
    float* out = array.mutable_data();
    const std::size_t pixels = static_cast<std::size_t>(height) * static_cast<std::size_t>(width);
    if (colour) {
      const char* components = name == "albedo" ? "RGB" : "XYZ";
      for (int c = 0; c < 3; ++c) {
        const std::vector<float>& plane = layers.channel(name + "." + components[c]);
        for (std::size_t i = 0; i < pixels; ++i) out[3 * i + static_cast<std::size_t>(c)] = plane[i];
      }
    } else {
      const std::vector<float>& plane = layers.channel(name == "depth" ? "depth.Z" : "samples.Y");
      std::memcpy(out, plane.data(), pixels * sizeof(float));
    }
    result.layers[name.c_str()] = array;
  }
  return result;
}

PyRender render(const PyScene& scene, const RenderArguments& arguments) {
  return with_number_format(arguments.number_format, [&]<class T>() { return render_with<T>(*scene.scene, arguments); });
}

// A scene given as a path, a dict or a Scene.
PyScene scene_of(const py::object& given, bool trust_model_paths) {
  if (py::isinstance<PyScene>(given)) return given.cast<PyScene>();
  if (py::isinstance<py::dict>(given)) return scene_from_dict(given.cast<py::dict>(), ".", trust_model_paths);
  if (py::isinstance<py::str>(given) || py::hasattr(given, "__fspath__"))
    return load_scene(py::module_::import("os").attr("fspath")(given).cast<std::string>(), trust_model_paths);
  throw py::type_error("scene: a path, a dict in the scene file's format, or a pathtracer.Scene");
}

void write_array(const std::filesystem::path& path, const py::array_t<float, py::array::c_style | py::array::forcecast>& pixels) {
  if (pixels.ndim() != 3 || pixels.shape(2) != 3)
    throw InputError(fmt::format("{}: the image must be an array of shape (height, width, 3)", path.string()));
  LinearImage image;
  image.height = static_cast<u32>(pixels.shape(0));
  image.width = static_cast<u32>(pixels.shape(1));
  image.rgb.assign(pixels.data(), pixels.data() + pixels.size());
  const py::gil_scoped_release released;
  write_image(path, image);
}

}  // namespace
}  // namespace pt

PYBIND11_MODULE(pathtracer, m) {
  using namespace pt;
  m.doc() = "pathtracer: a physically based Monte Carlo path tracer for CPUs and GPUs (docs/python.md)";
  m.attr("__version__") = PT_VERSION;
  // Bad input and failing devices: the one line the program prints after "pathtracer: error: ".
  static py::exception<std::exception> error(m, "Error");
  py::register_exception_translator([](std::exception_ptr raised) {
    try {
      if (raised) std::rethrow_exception(raised);
    } catch (const InputError& e) {
      error(e.what());
    } catch (const BackendError& e) {
      error(e.what());
    }
  });

  m.def("backends", &backend_names, "The backends this build has: cpu, auto (CUDA where a GPU is usable, else the CPU), cuda, sycl.");
  m.def("number_formats", &number_format_names, "The number formats the kernels are built for: float, double and fixed point (qI.F).");
  m.def(
      "devices",
      [] {
        py::list out;
        for (const DeviceDescription& d : describe_devices()) {
          if (d.index < 0) continue;
          py::dict entry;
          entry["backend"] = d.backend;
          entry["index"] = d.index;
          entry["name"] = d.name;
          out.append(entry);
        }
        return out;
      },
      "The devices of every backend built in, each a dict of backend, index (what device= or sycl_device= takes) and name.");

  py::class_<PyScene>(m, "Scene", "A scene, read and checked: from a scene file or model file, or from a dict in the scene file's format.")
      .def(py::init([](const py::object& path, bool trust_model_paths) {
             return load_scene(py::module_::import("os").attr("fspath")(path).cast<std::string>(), trust_model_paths);
           }),
           py::arg("path"), py::arg("trust_model_paths") = false)
      .def_static("from_dict", &scene_from_dict, py::arg("description"), py::arg("base_folder") = ".", py::arg("trust_model_paths") = false,
                  "A scene from a dict in the scene file's format; image and model paths are relative to base_folder.")
      .def_property_readonly(
          "settings", [](const PyScene& s) { return settings_dict(s.scene->render); }, "The scene's own render settings.")
      .def_property_readonly("source", [](const PyScene& s) { return s.scene->source; })
      .def_property_readonly("warnings", [](const PyScene& s) { return s.scene->warnings; })
      .def("__repr__", [](const PyScene& s) {
        return fmt::format("<pathtracer.Scene '{}' {}x{}, {} spp>", s.scene->source, s.scene->render.width, s.scene->render.height,
                           s.scene->render.samples_per_pixel);
      });

  py::class_<PyRender>(m, "Render", "A finished render: its image and how it went.")
      .def_readonly("image", &PyRender::image, "float32 array (height, width, 3): linear RGB, rows from the top")
      .def_readonly("samples_per_pixel", &PyRender::samples_per_pixel, "samples per pixel done (fewer than asked where stopped)")
      .def_readonly("stopped_early", &PyRender::stopped_early)
      .def_readonly("seconds", &PyRender::seconds, "wall time of the rendering passes")
      .def_readonly("samples", &PyRender::samples)
      .def_readonly("rays", &PyRender::rays)
      .def_readonly("dropped_samples", &PyRender::dropped_samples, "non-finite samples left out of their pixel")
      .def_readonly("backend", &PyRender::backend)
      .def_readonly("layers", &PyRender::layers,
                    "the render layers asked for (docs/python.md): albedo and normal (height, width, 3), depth and samples (height, width)")
      .def(
          "__array__", [](const PyRender& r, const py::object&) { return r.image; }, py::arg("dtype") = py::none());

  m.def(
      "render",
      [](const py::object& scene, std::optional<u32> width, std::optional<u32> height, std::optional<u32> spp, std::optional<u32> depth,
         std::optional<u32> seed, std::optional<std::string> light_sampling, std::optional<std::string> sampler, const std::string& backend,
         const std::string& device, unsigned threads, const std::string& integrator, const std::string& number_format, std::optional<int> sycl_device,
         std::optional<double> time_limit, const py::object& progress, const py::object& layers, bool trust_model_paths,
         std::optional<double> noise_threshold, std::optional<double> light_threshold, std::optional<double> merge_radius) {
        RenderArguments arguments;
        arguments.overrides = {width, height, spp, depth, seed, {}, {}, noise_threshold, light_threshold};
        if (light_sampling) {
          arguments.overrides.light_sampling = parse_light_sampling(*light_sampling);
          if (!arguments.overrides.light_sampling)
            throw InputError(fmt::format("light_sampling='{}': not one of auto, nee, none", *light_sampling));
        }
        if (sampler) {
          if (*sampler != "sobol" && *sampler != "independent")
            throw InputError(fmt::format("sampler='{}': not one of sobol, independent", *sampler));
          arguments.overrides.sampler = *sampler == "independent" ? SamplerKind::kIndependent : SamplerKind::kSobol;
        }
        if (time_limit && !(*time_limit > 0 && *time_limit < 1e300))
          throw InputError(fmt::format("time_limit={}: not a positive number of seconds", *time_limit));
        if (merge_radius && !(*merge_radius >= 0 && *merge_radius < 1e300))
          throw InputError(fmt::format("merge_radius={}: not a length of zero or more", *merge_radius));
        arguments.merge_radius = merge_radius.value_or(0);
        if (sycl_device && *sycl_device < 0) throw InputError(fmt::format("sycl_device={}: not a device index", *sycl_device));
        if (!progress.is_none() && !PyCallable_Check(progress.ptr())) throw py::type_error("progress: a callable, or None");
        arguments.backend = backend;
        arguments.device = device;
        arguments.threads = threads;
        arguments.integrator = integrator;
        arguments.number_format = number_format;
        arguments.sycl_device = sycl_device.value_or(-1);
        arguments.time_limit = time_limit.value_or(0);
        arguments.progress = progress;
        if (py::isinstance<py::str>(layers))
          arguments.layers = parse_layer_list(layers.cast<std::string>(), fmt::format("layers='{}'", clip(layers.cast<std::string>())));
        else if (!layers.is_none())
          arguments.layers = parse_layer_list(fmt::format("{}", fmt::join(layers.cast<std::vector<std::string>>(), ",")),
                                              fmt::format("layers={}", clip(py::repr(layers).cast<std::string>())));
        return render(scene_of(scene, trust_model_paths), arguments);
      },
      py::arg("scene"), py::kw_only(), py::arg("width") = py::none(), py::arg("height") = py::none(), py::arg("spp") = py::none(),
      py::arg("depth") = py::none(), py::arg("seed") = py::none(), py::arg("light_sampling") = py::none(), py::arg("sampler") = py::none(),
      py::arg("backend") = "cpu", py::arg("device") = "0", py::arg("threads") = 0u, py::arg("integrator") = "auto",
      py::arg("number_format") = "float", py::arg("sycl_device") = py::none(), py::arg("time_limit") = py::none(), py::arg("progress") = py::none(),
      py::arg("layers") = py::none(), py::arg("trust_model_paths") = false, py::arg("noise_threshold") = py::none(),
      py::arg("light_threshold") = py::none(), py::arg("merge_radius") = py::none(),
      "Renders a scene (a path, a dict or a Scene) with the scene's settings and the ones given, as `pathtracer render` does.\n"
      "progress(report) is called after every pass with a dict (samples_done, samples_total, elapsed_seconds,\n"
      "samples_per_second); returning False stops the render, which returns the image of the samples done.\n"
      "An exception in it, or Ctrl-C, stops the render and is raised. layers: 'albedo,normal', a list of names, or 'all'.\n"
      "noise_threshold: adaptive sampling, pixels stop once their estimated error as displayed (0..1) is below it.\n"
      "light_sampling: auto, nee or none; light_threshold: shadow rays that could add less are traced by chance (0: all).\n"
      "integrator: auto, megakernel, wavefront, bdpt or vcm; merge_radius: vcm's first merging radius (0 or None: from the camera).\n"
      "Returns a Render.");

  m.def("write_image", &write_array, py::arg("path"), py::arg("image"),
        "Writes a float array (height, width, 3) of linear RGB as PNG (8-bit sRGB), PFM or OpenEXR, by the extension, as the program does.");
}
