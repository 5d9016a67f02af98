// The command line: `pathtracer render SCENE -o IMAGE` with overrides, `pathtracer numerics SCENE`, `pathtracer devices`,
// --help, --version.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <numeric>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "app/distributed.hpp"
#include "app/numerics.hpp"
#include "app/render_overrides.hpp"
#include "backends/multi_backend.hpp"
#include "backends/registry.hpp"
#include "base/atomic_file.hpp"
#include "base/free_memory.hpp"
#include "base/input_file.hpp"
#include "base/number_formats.hpp"
#include "film/checkpoint.hpp"
#include "film/film.hpp"
#include "film/layers.hpp"
#include "loading/scene_loader.hpp"
#if PT_HAVE_PREVIEW
#include "preview/preview_server.hpp"
#endif

#ifndef PT_VERSION
#define PT_VERSION "0.0.0"
#endif
#ifndef PT_DEFAULT_SCENE
#define PT_DEFAULT_SCENE "scenes/seed-default.json"
#endif

namespace pt {
namespace {

// The exit status of every failure, bad input and failing devices alike (README.md, --help).
constexpr int kErrorExitCode = 1;

struct RenderOptions {
  std::string scene = PT_DEFAULT_SCENE;
  std::string output = "render.png";
  std::optional<u32> width, height, spp, depth, seed;
  unsigned threads = 0;
  std::string backend = "cpu";
  std::string device = "0";  // one device, or several (backends/registry.hpp, DeviceList)
  int sycl_device = -1;      // SYCL device index; negative: the runtime's default choice
  std::string number_format = "float";
  std::string integrator = "auto";
  std::optional<std::string> light_sampling;  // "auto", "nee" or "none"; the scene's (auto by default) if omitted
  std::optional<std::string> sampler;         // "sobol" or "independent"; the scene's (sobol by default) if omitted
  std::optional<double> noise_threshold;      // adaptive sampling; the scene's (off by default) if omitted
  std::optional<double> light_threshold;      // shadow-ray roulette; the scene's (0.01 by default) if omitted
  std::string bdpt_schedule = "auto";         // bidirectional path tracing: one-kernel, staged or auto
  double merge_radius = 0;                    // vcm: the first pass's merging radius; 0: from the camera (flatten.cpp)
  bool quiet = false;
  bool verbose = false;            // render only: the time of each phase
  std::string checkpoint, resume;  // render only: where the film is saved, and the saved film to go on from
  std::string layers;              // render only: render layers written beside the image (film/layers.hpp)
  double checkpoint_interval = 60;
  double time_limit = 0;
  u32 runs = 5;                    // bench only
  std::optional<int> preview;      // render only: the live preview's port (0: any free one)
  std::string preview_address = "127.0.0.1";
  bool trust_model_paths = false;  // model files may name files outside their folder
};

// "auto" lets the backend pick its device's faster integrator as measured in BENCHMARKS.md: the wavefront with
// CUDA (about 2x on material-heavy scenes), the megakernel on the host's processor (the wavefront's queues cost
// more there than they save) and with SYCL (its wavefront's intersect stage spills on GPUs).
Integrator integrator_of(const RenderOptions& options) {
  if (options.integrator == "wavefront") return Integrator::kWavefront;
  if (options.integrator == "megakernel") return Integrator::kMegakernel;
  if (options.integrator == "bdpt") return Integrator::kBidirectional;
  if (options.integrator == "vcm") return Integrator::kVertexMerging;
  return Integrator::kAuto;
}

std::string format_duration(double seconds) {
  if (seconds < 60) return fmt::format("{:.1f}s", seconds);
  const long s = static_cast<long>(seconds + 0.5);
  return s < 3600 ? fmt::format("{}m{:02}s", s / 60, s % 60) : fmt::format("{}h{:02}m", s / 3600, (s / 60) % 60);
}

std::string format_rate(double per_second) {
  if (per_second >= 1e9) return fmt::format("{:.2f} G", per_second / 1e9);
  if (per_second >= 1e6) return fmt::format("{:.2f} M", per_second / 1e6);
  if (per_second >= 1e3) return fmt::format("{:.2f} k", per_second / 1e3);
  return fmt::format("{:.0f} ", per_second);
}

// A one-line progress bar on stderr, redrawn in place; only when stderr is a terminal.
void draw_progress(const Progress& p) {
  const double fraction = static_cast<double>(p.samples_done) / p.samples_total;
  const int width = 30, filled = static_cast<int>(fraction * width);
  const double eta = fraction > 0 ? p.elapsed_seconds * (1 - fraction) / fraction : 0;
  fmt::print(stderr, "\r[{}{}] {:5.1f}%  elapsed {}  eta {}  {}samples/s   ", std::string(filled, '#'), std::string(width - filled, '.'),
             100 * fraction, format_duration(p.elapsed_seconds), format_duration(eta), format_rate(p.samples_per_second));
  if (p.samples_done == p.samples_total) fmt::print(stderr, "\n");
  std::fflush(stderr);
}

RenderSettings effective_settings(const RenderOptions& options, const SceneDescription& scene) {
  RenderOverrides overrides{options.width, options.height, options.spp, options.depth, options.seed, {}, {}, options.noise_threshold, options.light_threshold};
  if (options.light_sampling) overrides.light_sampling = parse_light_sampling(*options.light_sampling);
  if (options.sampler) overrides.sampler = *options.sampler == "independent" ? SamplerKind::kIndependent : SamplerKind::kSobol;
  RenderSettings settings = apply_overrides(scene, overrides, kCommandLineSpelling);
  settings.bidirectional_schedule = parse_bidirectional_schedule(options.bdpt_schedule).value_or(BidirectionalSchedule::kAuto);
  settings.merge_radius = options.merge_radius;
  return settings;
}

// SIGINT or SIGTERM: the first asks the render to stop after the pass under way (or to give it up, under MPI) and
// write what it has; a second ends the program at once, removing the temporaries of files being written. Before
// the render starts (the scene loading, its files read, the flattening) there is nothing to save, and the first
// ends the program at once. The status is 128 + the signal.
std::atomic<int> interrupt_signal{0};
std::atomic<bool> rendering{false};
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free, "the signal handler needs lock-free flags");

extern "C" void on_interrupt(int signal) {
  int none = 0;
  if (rendering.load() && interrupt_signal.compare_exchange_strong(none, signal)) return;
  remove_temporaries_now();
  _exit(128 + signal);
}

void catch_interrupts() {
  struct sigaction action {};
  action.sa_handler = on_interrupt;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;  // the file writes go on through the first signal
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

// Whether two paths name one file: by device and inode where both exist, else by their paths made absolute with
// links resolved.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  const std::optional<FileIdentity> first = identity_of(a), second = identity_of(b);
  if (first && second) return *first == *second;
  std::error_code ignored;
  return std::filesystem::weakly_canonical(a, ignored) == std::filesystem::weakly_canonical(b, ignored);
}

// Neither the image nor the checkpoint (run_render has checked that they are two files) is a file this render reads (the scene, its model files
// and images, a film resumed), compared by device and inode, not by name: an output never replaces an input. A
// resumed film may be saved again where it was read.
void check_outputs_are_not_inputs(const RenderOptions& options) {
  std::vector<FileRead> inputs = files_read();
  if (!options.resume.empty())
    if (const std::optional<FileIdentity> resumed = identity_of(options.resume)) inputs.push_back({*resumed, options.resume});
  const auto check = [&](const std::string& output, const char* what) {
    const std::optional<FileIdentity> identity = identity_of(output);
    if (!identity) return;
    for (const FileRead& input : inputs) {
      if (input.identity != *identity) continue;
      if (output == options.checkpoint && !options.resume.empty() && same_file(input.path, options.resume)) continue;
      throw InputError(fmt::format("{}: cannot write {} there: it is '{}', which this render reads", output, what, input.path.string()));
    }
  };
  check(options.output, "the image");
  if (!options.checkpoint.empty()) check(options.checkpoint, "the checkpoint");
}

// What a saved film must match to be resumed: the scene file's bytes and every setting that decides a sample.
CheckpointKey render_key(const RenderOptions& options, const SceneDescription& scene, const RenderSettings& settings) {
  return checkpoint_key_of_file(
      scene.source,
      fmt::format("depth {} seed {} roulette {} format {} lights {} sampler {} noise threshold {} light threshold {}", settings.max_depth, settings.seed,
                  settings.roulette_depth, options.number_format, light_sampling_name(settings.light_sampling),
                  sampler_name(settings.sampler), settings.noise_threshold, settings.light_threshold),
      settings.width, settings.height);
}

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// The phases of a command and their wall-clock seconds, printed by `render --verbose`.
class Phases {
 public:
  void add(std::string name, double seconds) { phases_.emplace_back(std::move(name), seconds); }
  // Times body() as the phase `name` and returns what it returns.
  template <class F>
  decltype(auto) time(std::string name, F&& body) {
    const auto start = Clock::now();
    struct Record {
      Phases& phases;
      std::string name;
      Clock::time_point start;
      ~Record() { phases.add(std::move(name), seconds_since(start)); }
    } record{*this, std::move(name), start};
    return body();
  }
  void print(double total) const {
    for (const auto& [name, seconds] : phases_) fmt::print(stderr, "  {:<24} {:8.4f} s\n", name, seconds);
    fmt::print(stderr, "  {:<24} {:8.4f} s\n", "total (from the start)", total);
  }

 private:
  std::vector<std::pair<std::string, double>> phases_;
};

// The device starts (a GPU's context creation takes a good part of a second) while the scene loads and flattens.
// Under MPI (`mpi` given: this is rank 0) the other ranks render bands of the image too, and the film is gathered
// here, the only rank that writes.
template <class T>
int render_with(const RenderOptions& options, Clock::time_point program_start, Distributed* mpi) {
  Phases phases;
  double device_seconds = 0;
  const DeviceList devices = parse_device_list(options.device, options.backend);
  std::future<std::unique_ptr<RenderBackend<T>>> starting = std::async(std::launch::async, [&] {
    const auto start = Clock::now();
    std::unique_ptr<RenderBackend<T>> made =
        make_render_backend<T>(options.backend, devices, options.threads, integrator_of(options), options.sycl_device);
    device_seconds = seconds_since(start);
    return made;
  });
  SceneDescription scene =
      phases.time("scene load", [&] { return load_scene_file(options.scene, model_references(options.trust_model_paths)); });
  if (!options.quiet)
    for (const std::string& warning : scene.warnings) fmt::print(stderr, "warning: {}\n", escape_control_characters(warning));
  const RenderSettings settings = effective_settings(options, scene);
  // What follows needs only the description's source: its objects, materials and textures go once converted.
  // The CPU backend walks only the wide tree in floating point: the binary one is not kept then (a large scene's largest
  // array after the primitives). Fixed point walks the binary tree everywhere (kernel/bvh.hpp, walk_tree).
  const bool binary_tree = options.backend != "cpu" || !std::is_floating_point_v<T>;
  const FlatScene<T> flat = phases.time("flatten (BVH included)", [&] { return flatten_scene_releasing<T>(scene, settings, 0, binary_tree); });
  phases.add("  of which BVH build", flat.bvh_seconds);
  check_outputs_are_not_inputs(options);
  const auto wait_start = Clock::now();
  std::unique_ptr<RenderBackend<T>> backend = starting.get();
  phases.add("device start (overlapped)", device_seconds);
  phases.add("waiting for the device", seconds_since(wait_start));
  const CheckpointKey key = render_key(options, scene, settings);
  if (mpi) {
    std::vector<std::unique_ptr<BandWorker>> remote = phases.time("waiting for the other ranks", [&] { return mpi->gather_workers(key.hash); });
    std::vector<std::unique_ptr<RenderBackend<T>>> local;
    local.push_back(std::move(backend));
    backend = std::make_unique<MultiBackend<T>>(std::move(local), std::move(remote), mpi->where(0));
  }
  const bool show_progress = !options.quiet && isatty(STDERR_FILENO);
  if (!options.quiet) {
    fmt::print(stderr, "{}: {}x{}, {} spp, depth {}, {} primitives, backend {}, {}\n", scene.source, settings.width, settings.height,
               settings.samples_per_pixel, settings.max_depth, flat.primitives.size(), backend->name(), options.number_format);
    if (flat.scale != 1) fmt::print(stderr, "lengths scaled by {:g} to fit {} (docs/numerics.md)\n", flat.scale, options.number_format);
  }
  RenderControl control;
  control.stop_requested = [] { return interrupt_signal.load() != 0; };
  control.time_limit_seconds = options.time_limit;
  // A checkpoint that cannot be written (a full disk) does not cost the render: it goes on, saying so once, later
  // saves try again, and the image is written; the status is then 1, naming what failed.
  std::optional<std::string> checkpoint_failure;
  if (!options.checkpoint.empty()) {
    control.checkpoint_interval_seconds = options.checkpoint_interval;
    control.checkpoint = [&](std::span<const FilmPixel> pixels, u32 samples_done) {
      try {
        write_checkpoint(options.checkpoint, key, pixels, samples_done);
        checkpoint_failure.reset();
      } catch (const InputError& e) {
        if (!checkpoint_failure && !options.quiet) fmt::print(stderr, "{}warning: {}; rendering on\n", show_progress ? "\n" : "", e.what());
        checkpoint_failure = e.what();
      }
    };
  }
  Checkpoint resumed;
  if (!options.resume.empty()) {
    resumed = read_checkpoint(options.resume, key);
    if (resumed.samples_done > settings.samples_per_pixel)
      throw InputError(fmt::format("{}: cannot resume: it holds {} samples per pixel, more than the {} asked for", options.resume,
                                   resumed.samples_done, settings.samples_per_pixel));
    control.start_film = resumed.film;
    control.start_samples = resumed.samples_done;
    if (!options.quiet)
      fmt::print(stderr, "resuming {} at {} of {} samples per pixel\n", options.resume, resumed.samples_done, settings.samples_per_pixel);
  }
  // The image with its layers: at the end, and where the preview page asks to save now.
  const auto write_output = [&](const RenderedFilm& film, Phases* timed) {
    ImageRows rows = film_rows(film);
    RenderLayers layers;
    if (!options.layers.empty()) {
      const auto make_layers = [&] {
        return render_layers(*backend, flat, film, parse_layer_list(options.layers, "--layers " + clip(options.layers)));
      };
      layers = timed ? timed->time("layers", make_layers) : make_layers();
      rows.channels = layers.image_channels();
    }
    if (timed)
      timed->time("resolve, encode and write", [&] { write_image(options.output, rows); });
    else
      write_image(options.output, rows);
  };
  ProgressCallback progress = show_progress ? ProgressCallback(draw_progress) : ProgressCallback();
#if PT_HAVE_PREVIEW
  // The live preview: frames only while a page watches; its stop is an interrupt's, its "save now" writes the image
  // of the samples done (and the checkpoint) and renders on.
  std::unique_ptr<PreviewServer> preview;
  if (options.preview) {
    // The page's title: the scene's file name (its folder says nothing the person watching needs).
    const std::string title = options.scene.empty() ? scene.source : std::filesystem::path(options.scene).filename().string();
    preview = std::make_unique<PreviewServer>(options.preview_address, static_cast<unsigned>(*options.preview), title);
    fmt::print(stderr, "preview: {} (open it in a browser)\n", preview->url());
    const auto to_preview = [](const Progress& p) { return PreviewProgress{p.samples_done, p.samples_total, p.elapsed_seconds, p.samples_per_second}; };
    progress = [&, to_preview, drawn = progress](const Progress& p) {
      if (drawn) drawn(p);
      preview->report(to_preview(p));
    };
    control.watching = [&] { return preview->watched(); };
    control.show = [&, to_preview](std::span<const FilmPixel> pixels, const Progress& p) {
      preview->show(pixels, settings.width, settings.height, to_preview(p));
    };
    control.save_requested = [&] { return preview->take_save_request(); };
    control.save_image = [&](std::span<const FilmPixel> pixels, u32 samples_done) {
      RenderedFilm now;
      now.on_backend = pixels;
      now.width = settings.width;
      now.height = settings.height;
      now.samples_done = samples_done;
      try {
        write_output(now, nullptr);
        preview->say(fmt::format("saved {} at {} samples per pixel", options.output, samples_done));
      } catch (const InputError& e) {
        // Like a checkpoint's, a failed save does not cost the render; the last line says it failed.
        preview->say(e.what());
        if (!options.quiet) fmt::print(stderr, "{}warning: {}; rendering on\n", show_progress ? "\n" : "", e.what());
      }
    };
    control.stop_requested = [&] { return interrupt_signal.load() != 0 || preview->stop_requested(); };
  }
  // Whatever ends the render, the page is told how.
  struct EndPreview {
    std::unique_ptr<PreviewServer>& preview;
    PreviewState state = PreviewState::kFailed;
    std::string message = "the render failed: the program's output says why";
    ~EndPreview() {
      if (preview) preview->finish(state, message);
    }
  } end_preview{preview};
#else
  if (options.preview) throw InputError("--preview: this build has no preview (it needs cpp-httplib: Debian's libcpp-httplib-dev)");
#endif
  // The film is resolved band by band as the image is encoded, never copied whole (BENCHMARKS.md, memory).
  rendering = true;
  const RenderedFilm film = render_film(*backend, flat, progress, control);
  if (show_progress && film.stopped_early) fmt::print(stderr, "\n");
  const int caught = interrupt_signal.load();
#if PT_HAVE_PREVIEW
  const bool stopped_by_page = preview && film.stopped_early && caught == 0 && preview->stop_requested();
  if (preview && preview->watched())
    preview->show(film.pixels(), film.width, film.height,
                  PreviewProgress{film.samples_done, settings.samples_per_pixel, film.stats.seconds, film.stats.samples / std::max(film.stats.seconds, 1e-9)});
#else
  const bool stopped_by_page = false;
#endif
  if (film.samples_done == 0) {
    if (!options.quiet) fmt::print(stderr, "stopped before the first sample: nothing written\n");
#if PT_HAVE_PREVIEW
    end_preview.state = PreviewState::kStopped;
    end_preview.message = "stopped before the first sample: nothing written";
#endif
    return caught ? 128 + caught : 0;
  }
  phases.add("upload", film.stats.upload_seconds);
  phases.add("render", film.stats.seconds);
  if (const std::optional<double> on_device = backend->device_seconds()) phases.add("  of which on the device", *on_device);
  phases.add("read-back", film.stats.read_back_seconds);
  write_output(film, &phases);
#if PT_HAVE_PREVIEW
  end_preview.state = film.stopped_early ? PreviewState::kStopped : PreviewState::kFinished;
  end_preview.message = fmt::format("wrote {}", options.output);
#endif
  if (!options.quiet) {
    const RenderStats& s = film.stats;
    fmt::print(stderr, "wrote {}: {:.3f} s, {}samples/s, {}rays/s, {} non-finite samples dropped\n", options.output, s.seconds,
               format_rate(s.samples / s.seconds), format_rate(s.rays / s.seconds), s.dropped_samples);
    const std::vector<std::pair<std::string, u64>> shares = backend->work_shares();
    u64 all = 0;
    for (const auto& share : shares) all += share.second;
    for (const auto& [name, share] : shares) fmt::print(stderr, "  {:5.1f}% of the samples: {}\n", all ? 100.0 * share / all : 0.0, name);
    for (const std::string& line : backend->report()) fmt::print(stderr, "  {}\n", line);
    if (film.stopped_early)
      fmt::print(stderr, "stopped by {} after {} of {} samples per pixel{}\n",
                 caught                ? (caught == SIGINT ? "an interrupt (SIGINT)" : "SIGTERM")
                 : stopped_by_page     ? "the preview page"
                                       : "the time limit",
                 film.samples_done, settings.samples_per_pixel,
                 options.checkpoint.empty() || checkpoint_failure ? "" : fmt::format("; film saved to {}", options.checkpoint));
    if constexpr (is_fixed_v<T>) fmt::print(stderr, "{} fixed-point saturation events\n", s.saturations);
  }
  if (options.verbose) {
    phases.print(seconds_since(program_start));
    const std::size_t sampled = flat.params.next_event ? flat.light_entries.size() : 0;
    fmt::print(stderr, "  light sampling {}: {} light{} by next-event estimation, the background {} (its relative variance under scattering {:.3g})\n",
               light_sampling_name(settings.light_sampling), sampled, sampled == 1 ? "" : "s",
               sampled > 0 && flat.background_light != kNoLight ? "among them" : "found by scattering", flat.background_scattering_variance);
  }
  if (checkpoint_failure) {
    fmt::print(stderr, "pathtracer: error: {} (the image was written to {})\n", *checkpoint_failure, options.output);
    return kErrorExitCode;
  }
  // A signal that came while the image was written (the write goes on through it) still ends the program with its
  // status, so that a script can tell; the image is whole.
  const int signal_at_end = interrupt_signal.load();
  if (signal_at_end != 0 && caught == 0 && !options.quiet)
    fmt::print(stderr, "{} arrived after the render had finished: the image of all {} samples per pixel is complete\n",
               signal_at_end == SIGINT ? "an interrupt (SIGINT)" : "SIGTERM", film.samples_done);
  return signal_at_end != 0 ? 128 + signal_at_end : 0;
}

int run_render(const RenderOptions& options, Clock::time_point program_start, Distributed* mpi = nullptr) {
  // Fail on an unusable output name or place before spending time on the render.
  const ImageFormat format = image_format_for(options.output);
  if (!options.layers.empty()) {
    parse_layer_list(options.layers, "--layers " + clip(options.layers));
    if (format != ImageFormat::kExr)
      throw InputError(
          fmt::format("--layers {}: only OpenEXR holds render layers, and {} is not an .exr file", clip(options.layers), options.output));
  }
  check_output_path(options.output);
  if (!options.checkpoint.empty()) check_output_path(options.checkpoint);
  if (!options.checkpoint.empty() && same_file(options.output, options.checkpoint))
    throw InputError(fmt::format("{}: cannot write the image and the checkpoint to one file", options.output));
  catch_interrupts();
  return with_number_format(options.number_format, [&]<class T>() { return render_with<T>(options, program_start, mpi); });
}

// A rank other than 0 of an MPI run: loads the scene as rank 0 does, says it is ready, and renders the bands it is
// sent until rank 0 says the run is over. It prints nothing: its failures go to rank 0, which reports them.
template <class T>
void serve_with(const RenderOptions& options, Distributed& mpi) {
  std::optional<FlatScene<T>> flat;  // kept while the backend renders: the CPU reads the scene's arrays in place
  std::unique_ptr<RenderBackend<T>> backend;
  u32 width = 0;
  try {
    const SceneDescription scene = load_scene_file(options.scene, model_references(options.trust_model_paths));
    const RenderSettings settings = effective_settings(options, scene);
    flat.emplace(flatten_scene<T>(scene, settings));
    backend = make_render_backend<T>(options.backend, parse_device_list(options.device, options.backend), options.threads, integrator_of(options),
                                     options.sycl_device);
    backend->upload(*flat);
    width = settings.width;
    mpi.report_ready(render_key(options, scene, settings).hash, backend->name());
  } catch (const std::bad_alloc&) {
    mpi.report_failure("out of memory");
  } catch (const std::exception& e) {
    mpi.report_failure(e.what());
  }
  rendering = true;
  mpi.serve(width, [&](const BandWork& work, std::span<FilmPixel> band) {
    if (!backend) throw BackendError("this rank failed at its start");
    backend->render_rows(work.first_row, work.row_count, work.first_sample, work.sample_count, band);
  });
}

// `render` under an MPI launcher (docs/distributed.md): rank 0 renders with the others and alone writes and
// reports; any rank's failure is reported once, by rank 0, naming the rank and its host, and nothing is written.
int run_distributed_render(const RenderOptions& options, Clock::time_point program_start, int& argc, char**& argv) {
  std::optional<Distributed> mpi;
  try {
    mpi.emplace(argc, argv);
  } catch (const std::exception& e) {
    fmt::print(stderr, "pathtracer: error: {}\n", e.what());
    return kErrorExitCode;
  }
  int status = kErrorExitCode;
  if (mpi->rank() != 0) {
    catch_interrupts();  // rank 0 decides when to stop; a second signal still ends a rank at once
    with_number_format(options.number_format, [&]<class T>() {
      serve_with<T>(options, *mpi);
      return 0;
    });
    status = 0;
  } else {
    try {
      status = run_render(options, program_start, &*mpi);
    } catch (const RemoteError& e) {
      fmt::print(stderr, "pathtracer: error: {}\n", e.what());
    } catch (const std::bad_alloc&) {
      fmt::print(stderr, "pathtracer: error: {}: out of memory\n", mpi->where(0));
    } catch (const std::exception& e) {
      fmt::print(stderr, "pathtracer: error: {}: {}\n", mpi->where(0), e.what());
    }
    mpi->stop_all();
    mpi->finish(status);
  }
  mpi.reset();  // MPI_Finalize: waits for every rank
  return status;
}

// Renders the scene `runs` times after a short warm-up and reports the median: the benchmark of BENCHMARKS.md.
template <class T>
int bench_with(const RenderOptions& options, const SceneDescription& scene, const RenderSettings& settings) {
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  std::unique_ptr<RenderBackend<T>> backend = make_render_backend<T>(options.backend, parse_device_list(options.device, options.backend),
                                                                     options.threads, integrator_of(options), options.sycl_device);
  {
    // Warm-up: module loading, first-touch of memory, thread start-up stay out of the timed runs.
    FlatScene<T> warm = flat;
    warm.samples_per_pixel = 1;
    render_scene(*backend, warm);
  }
  std::vector<double> seconds, wall_seconds;
  RenderStats stats;
  for (u32 run = 0; run < options.runs; ++run) {
    const RenderResult result = render_scene(*backend, flat);
    stats = result.stats;
    seconds.push_back(backend->device_seconds().value_or(result.stats.seconds));
    wall_seconds.push_back(result.stats.seconds);
    fmt::print(stderr, "run {}: {:.4f} s\n", run + 1, seconds.back());
  }
  std::string stages;
  for (const auto& [stage, stage_seconds] : backend->stage_seconds())
    stages += fmt::format("{}{} {:.1f}%", stages.empty() ? " | stages: " : ", ", stage, 100 * stage_seconds / seconds.back());
  std::vector<double> sorted = seconds;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[sorted.size() / 2];
  // The wall clock too, which compares a device's events with paths that have none (several devices in bands).
  std::sort(wall_seconds.begin(), wall_seconds.end());
  const double wall_median = wall_seconds[wall_seconds.size() / 2];
  fmt::print(
      "scene {} | {}x{} {} spp depth {} | backend {} | {} | median of {}: {:.4f} s ({} timing) | {}samples/s | {}rays/s | "
      "{:.2f} rays/sample | dropped {} | scene {:.1f} MB | wall-clock median {:.4f} s{}\n",
      scene.source, settings.width, settings.height, settings.samples_per_pixel, settings.max_depth, backend->name(), options.number_format,
      options.runs, median, backend->device_seconds() ? "device-event" : "wall-clock", format_rate(stats.samples / median),
      format_rate(stats.rays / median), static_cast<double>(stats.rays) / stats.samples, stats.dropped_samples, flat.bytes() / 1e6, wall_median,
      stages);
  return 0;
}

int run_bench(const RenderOptions& options) {
  const SceneDescription scene = load_scene_file(options.scene, model_references(options.trust_model_paths));
  const RenderSettings settings = effective_settings(options, scene);
  return with_number_format(options.number_format, [&]<class T>() { return bench_with<T>(options, scene, settings); });
}

// Ends the process once its work is done and written, without the static destructors and exit handlers: a GPU
// runtime's teardown of its context takes tens of milliseconds that nobody waits for usefully. Sanitizer builds exit
// normally, so that their checks at exit (leaks) still run.
[[noreturn]] void exit_without_teardown(int status) {
  std::fflush(stdout);
  std::fflush(stderr);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  std::exit(status);
#else
  std::_Exit(status);
#endif
}

// "; did you mean 'NAME'?" for the one name within two edits of `typed` (Levenshtein distance), else "".
std::string closest_name_hint(std::string_view typed, const std::vector<std::string>& names) {
  const auto distance = [](std::string_view a, std::string_view b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
      std::size_t diagonal = row[0];
      row[0] = i;
      for (std::size_t j = 1; j <= b.size(); ++j) {
        const std::size_t above = row[j];
        row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
        diagonal = above;
      }
    }
    return row[b.size()];
  };
  std::vector<std::string> near;
  if (typed.size() <= 64)
    for (const std::string& name : names)
      if (distance(typed, name) <= 2) near.push_back(name);
  return near.size() == 1 ? "; did you mean '" + near[0] + "'?" : "";
}

}  // namespace
}  // namespace pt

int main(int argc, char** argv) {
  using namespace pt;
  const auto program_start = Clock::now();
  return_large_blocks_when_freed();
  CLI::App app{"pathtracer: a physically based Monte Carlo path tracer for CPUs and GPUs"};
  app.set_version_flag("--version", std::string("pathtracer ") + PT_VERSION);
  app.require_subcommand(1);
  // Command-line mistakes get the same one-line form and exit status as every other input error.
  app.failure_message([](const CLI::App*, const CLI::Error& e) { return std::string("pathtracer: error: ") + e.what() + "\n"; });
  app.footer(
      fmt::format("Exit status: 0 on success; {} on any error: bad input (command line, scene file, images, output place, a\n"
                  "failed write) or a failing device, with one line 'pathtracer: error: ...' on stderr; 130 or 143 when a\n"
                  "render stopped by SIGINT or SIGTERM has written what it had. Images are at most\n"
                  "{} pixels a side and {} pixels in all.",
                  kErrorExitCode, kMaxImageSide, kMaxImagePixels));

  RenderOptions options;
  CLI::App* render = app.add_subcommand("render", "Render a scene file to an image (PNG, PFM or OpenEXR, by extension)");
  CLI::App* bench = app.add_subcommand("bench", "Render a scene several times and print the median speed (nothing is written)");
  for (CLI::App* command : {render, bench}) {
    command->add_option("scene", options.scene, "Scene file (JSON); the seed's default scene if omitted");
    command->add_option("--width", options.width, "Image width in pixels")->check(CLI::Range(1u, kMaxImageSide));
    command->add_option("--height", options.height, "Image height in pixels")->check(CLI::Range(1u, kMaxImageSide));
    command->add_option("--spp", options.spp, "Samples per pixel")->check(CLI::Range(1u, kMaxSamplesPerPixel));
    command->add_option("--depth", options.depth, "Maximum path depth (bounces)")->check(CLI::Range(1u, kMaxDepth));
    command->add_option("--seed", options.seed, "Random seed");
    command->add_option("--threads", options.threads, "CPU threads (0: all cores)")->check(CLI::Range(0u, 4096u));
    command->add_option("--backend", options.backend, "Backend: " + backend_choices())->check(CLI::IsMember(backend_names()))->capture_default_str();
    command
        ->add_option("--device", options.device,
                     "Device: a GPU index; all (every GPU, or the CPU); local-rank (the GPU of this MPI rank on its node); cpu; or "
                     "several joined by commas (0,2,3 or 0,cpu; cpu,cpu: CPU devices sharing --threads), rendering one image in bands "
                     "(docs/distributed.md)")
        ->capture_default_str();
    command
        ->add_option("--sycl-device", options.sycl_device,
                     "Device index for the sycl backend (see `pathtracer devices`; default: the runtime's choice)")
        ->check(CLI::NonNegativeNumber);
    command
        ->add_option("--integrator", options.integrator,
                     "megakernel (each path in one go), wavefront (stages over queues), auto (each backend's faster one), bdpt "
                     "(bidirectional path tracing: light and camera subpaths joined, for caustics) or vcm (bdpt with vertex merging, "
                     "for caustics seen through glass or in mirrors; consistent, not unbiased: docs/light-transport.md)")
        ->check(CLI::IsMember({"auto", "megakernel", "wavefront", "bdpt", "vcm"}))
        ->capture_default_str();
    command
        ->add_option("--merge-radius", options.merge_radius,
                     "vcm: the radius within which the first pass merges light vertices, in the scene's units; later passes "
                     "shrink it. 0: the width of a pixel at the distance the camera looks at, at most a 512th of the view's height there")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    command
        ->add_option("--bdpt-schedule", options.bdpt_schedule,
                     "How bdpt runs on a device: one-kernel (each sample in one launch), staged (subpaths, then their connections as a "
                     "launch of their own, over bands of rows) or auto (staged on GPUs, one kernel on the CPU); the same image either way")
        ->check(CLI::IsMember({"auto", "one-kernel", "staged"}))
        ->capture_default_str();
    command
        ->add_option("--light-sampling", options.light_sampling,
                     "auto (next-event estimation of every emitting shape, and of the background only where it varies enough to "
                     "pay), nee (a shadow ray to a light, the background included, at every diffuse bounce, with multiple importance "
                     "sampling) or none (lights found only by scattering); the scene's, else auto, if omitted")
        ->check(CLI::IsMember({"auto", "nee", "none"}));
    command
        ->add_option("--sampler", options.sampler,
                     "sobol (each pixel's samples stratified in every dimension: Owen-scrambled Sobol points) or independent "
                     "(uncorrelated random numbers); the scene's, else sobol, if omitted")
        ->check(CLI::IsMember({"sobol", "independent"}));
    command->add_option("--noise-threshold", options.noise_threshold,
                        "Adaptive sampling: a pixel stops taking samples once its estimated error as displayed (0..1) is below this (e.g. 0.01; "
                        "0: off; docs/adaptive-sampling.md); the scene's, else 0, if omitted");
    command->add_option("--light-threshold", options.light_threshold,
                        "Shadow rays whose light could add less than this radiance to a sample are traced by chance and weighted by its "
                        "inverse (the same expected image, fewer rays towards faint or far lights; 0: every one is traced); the scene's, "
                        "else 0.01, if omitted");
    command->add_flag("--trust-model-paths", options.trust_model_paths,
                      "Let model files (OBJ, MTL, glTF) name files outside their own folder: absolute paths, '..', links that lead out");
    command->add_option("--number-format", options.number_format, "Scalar type of the kernels (qI.F: fixed point, docs/numerics.md)")
        ->check(CLI::IsMember(number_format_names()))
        ->capture_default_str();
  }
  render->add_option("-o,--output", options.output, "Output image: .png (8-bit sRGB), .pfm or .exr (linear float)")->capture_default_str();
  render->add_flag("-q,--quiet", options.quiet, "No progress and no summary");
  render->add_flag("-v,--verbose", options.verbose,
                   "Print the time of each phase (device start, scene load, BVH build, upload, render, read-back, encode)");
  // CLI11's PositiveNumber lets "nan" and "inf" through (no comparison fails for NaN).
  const CLI::Validator seconds(
      [](const std::string& text) {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value) || !(value > 0))
          return fmt::format("'{}' is not a positive number of seconds", clip(text));
        return std::string();
      },
      "SECONDS > 0");
  render->add_option("--time-limit", options.time_limit, "Stop after this many seconds of rendering (at least one pass) and write the image so far")
      ->check(seconds);
  render->add_option("--checkpoint", options.checkpoint,
                     "Save the film to this file now and then, when stopped, and at the end (resume it with --resume)");
  render->add_option("--checkpoint-interval", options.checkpoint_interval, "Seconds between saves of the film")
      ->check(seconds)
      ->capture_default_str();
  render->add_option("--layers", options.layers,
                     "Render layers written as channels of the OpenEXR image: albedo, normal, depth, samples (comma-separated), or all");
  render->add_option("--resume", options.resume, "Go on from a film saved by --checkpoint (same scene and settings; --spp may be raised)");
  render
      ->add_option("--preview", options.preview,
                   "Show the render converging in a browser: serve a page on this port (0: any free one), with 'save now' and 'stop' (docs/preview.md)")
      ->expected(0, 1)
      ->default_str("8470")
      ->check(CLI::Range(0, 65535));
  render->add_option("--preview-address", options.preview_address, "Address the preview listens on (another than loopback lets other machines in)")
      ->capture_default_str();
  bench->add_option("--runs", options.runs, "Timed runs (the median is reported)")->check(CLI::Range(1u, 1000u))->capture_default_str();

  NumericsOptions numerics_options;
  CLI::App* numerics = app.add_subcommand("numerics", "Render a scene in every number format and measure each against double (docs/numerics.md)");
  numerics->add_option("scene", numerics_options.scene, "Scene file (JSON)")->required();
  numerics->add_option("-o,--output", numerics_options.output_folder, "Folder for the CSV table, the SVG plot and the images")->capture_default_str();
  numerics->add_option("--width", numerics_options.width, "Image width in pixels")->check(CLI::Range(1u, kMaxImageSide))->capture_default_str();
  numerics->add_option("--height", numerics_options.height, "Image height in pixels")->check(CLI::Range(1u, kMaxImageSide))->capture_default_str();
  numerics->add_option("--spp", numerics_options.spp, "Samples per pixel")->check(CLI::Range(1u, kMaxSamplesPerPixel))->capture_default_str();
  numerics->add_option("--depth", numerics_options.depth, "Maximum path depth (bounces); the scene's if omitted")->check(CLI::Range(1u, kMaxDepth));
  numerics->add_option("--seed", numerics_options.seed, "Random seed; the scene's if omitted");
  numerics->add_option("--threads", numerics_options.threads, "CPU threads (0: all cores)")->check(CLI::Range(0u, 4096u));
  numerics->add_option("--formats", numerics_options.formats, "Formats to compare (default: all built in)")
      ->check(CLI::IsMember(number_format_names()));
  numerics->add_flag("--bdpt", numerics_options.bidirectional, "Render with bidirectional path tracing instead of the path tracer");
  numerics->add_flag("--trust-model-paths", numerics_options.trust_model_paths, "Let model files name files outside their own folder");

  CLI::App* devices = app.add_subcommand("devices", "List the devices of every backend built in");

  // CLI11 says only "A subcommand is required" of a mistyped command: name it, and the command meant.
  std::vector<std::string> names;
  for (const CLI::App* command : app.get_subcommands({})) names.push_back(command->get_name());
  if (argc > 1 && argv[1][0] != '-' && std::find(names.begin(), names.end(), argv[1]) == names.end()) {
    fmt::print(stderr, "pathtracer: error: '{}' is not a command ({}){}\n", clip(argv[1]), fmt::join(names, ", "), closest_name_hint(argv[1], names));
    return kErrorExitCode;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version arrive here too, with status 0; CLI11's own codes for mistakes (104-114) are replaced
    // by the one documented code.
    const int status = app.exit(e);
    return status == 0 ? 0 : kErrorExitCode;
  }
  try {
    if (*devices) {
      list_devices();
      return 0;
    }
    if ((*render || *bench) && options.sycl_device >= 0 && options.backend != "sycl")
      throw InputError(fmt::format("--sycl-device {}: only the sycl backend takes it ({})", options.sycl_device,
                                   std::ranges::count(backend_names(), std::string("sycl")) == 0 ? "this build has none" : "--backend sycl"));
    if (*bench) return run_bench(options);
    if (*numerics) return run_numerics(numerics_options);
    if (launched_by_mpi()) exit_without_teardown(run_distributed_render(options, program_start, argc, argv));
    const int status = run_render(options, program_start);
    exit_without_teardown(status);
  } catch (const InputError& e) {
    fmt::print(stderr, "pathtracer: error: {}\n", e.what());
  } catch (const BackendError& e) {
    fmt::print(stderr, "pathtracer: error: {}\n", e.what());
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "pathtracer: error: out of memory\n");
  } catch (const std::exception& e) {
    fmt::print(stderr, "pathtracer: error: {}\n", e.what());
  }
  return kErrorExitCode;
}
