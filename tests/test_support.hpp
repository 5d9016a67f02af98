// Shared helpers of the test suite: paths, temporary folders, random numbers, rendering, pixel statistics, PFM reading.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "backends/cpu/cpu_backend.hpp"
#include "backends/cpu/parallel_loop.hpp"
#include "film/film.hpp"
#include "flat/flat_scene.hpp"
#include "image/image_io.hpp"
#include "scene/scene_loader.hpp"

#ifndef PT_SOURCE_DIR
#error "PT_SOURCE_DIR must name the source tree"
#endif

namespace pt::test {

// The source tree: where it was configured, unless PT_SOURCE_DIR in the environment says it moved (the suite is
// also run from a copy on a GPU machine).
inline std::filesystem::path source_dir() {
  const char* moved = std::getenv("PT_SOURCE_DIR");
  return std::filesystem::path(moved && *moved ? moved : PT_SOURCE_DIR);
}
inline std::filesystem::path scenes_dir() { return source_dir() / "scenes"; }
inline std::filesystem::path scene_path(const std::string& name) { return scenes_dir() / name; }

// A fresh folder under the system's temporary folder, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    static std::atomic<unsigned> counter{0};
    std::random_device entropy;
    const std::string name = "pathtracer-tests-" + std::to_string(getpid()) + "-" + std::to_string(counter++) + "-" + std::to_string(entropy());
    path_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code error;
    // Folders a test made read-only must become writable again before their contents can go.
    for (auto it = std::filesystem::recursive_directory_iterator(path_, error); !error && it != std::filesystem::recursive_directory_iterator();
         it.increment(error))
      if (it->is_directory(error)) std::filesystem::permissions(it->path(), std::filesystem::perms::owner_all, std::filesystem::perm_options::add, error);
    std::filesystem::permissions(path_, std::filesystem::perms::owner_all, std::filesystem::perm_options::add, error);
    std::filesystem::remove_all(path_, error);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

  // Names of the entries directly inside the folder, sorted.
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(path_)) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  std::filesystem::path path_;
};

inline void write_text_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

inline std::string read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// SplitMix64: the same sequence on every platform and standard library (std::uniform_real_distribution is not).
struct TestRandom {
  u64 state;
  explicit TestRandom(u64 seed) : state(seed) {}
  u64 next() {
    u64 z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  Vec3d vec3(double lo, double hi) { return {uniform(lo, hi), uniform(lo, hi), uniform(lo, hi)}; }
  Vec3d unit_vector() {
    const double u1 = uniform();  // drawn in a fixed order (function arguments have none)
    return uniform_unit_vector(u1, uniform());
  }
  u32 below(u32 n) { return static_cast<u32>(next() % n); }
};

template <class T>
Vec3<T> to(const Vec3d& v) {
  return {static_cast<T>(v.x), static_cast<T>(v.y), static_cast<T>(v.z)};
}

// Parses scene text as if it were a file in scenes/ (so image paths such as textures/... resolve).
inline SceneDescription parse(const std::string& json, const std::string& source = "test.json") {
  return parse_scene(json, source, scenes_dir());
}

template <class T>
FlatScene<T> flatten(const SceneDescription& scene) {
  return flatten_scene<T>(scene, scene.render);
}

template <class T>
RenderResult render(const FlatScene<T>& scene, unsigned threads = 0, Integrator integrator = Integrator::kMegakernel) {
  const std::unique_ptr<RenderBackend<T>> backend = make_cpu_backend<T>(threads, integrator);
  return render_scene(*backend, scene);
}

// Renders a film directly through the backend interface, with the given split of the samples into calls.
template <class T>
std::vector<FilmPixel> render_film(const FlatScene<T>& scene, unsigned threads, const std::vector<u32>& passes,
                                   Integrator integrator = Integrator::kMegakernel) {
  const std::unique_ptr<RenderBackend<T>> backend = make_cpu_backend<T>(threads, integrator);
  backend->upload(scene);
  u32 first = 0;
  for (u32 count : passes) {
    backend->render(first, count);
    first += count;
  }
  std::vector<FilmPixel> film;
  backend->read_film(film);
  return film;
}

// Mean and variance (of one sample) of every pixel's finite samples, channel by channel, computed from the
// individual samples of the integrator (the film only keeps sums).
struct PixelStatistics {
  u32 width = 0, height = 0, samples = 0;
  std::vector<double> mean;      // 3 per pixel
  std::vector<double> variance;  // 3 per pixel, unbiased
  u64 non_finite = 0;

  std::size_t values() const { return mean.size(); }
  double standard_error(std::size_t i) const { return std::sqrt(variance[i] / samples); }
  double image_mean(int channel) const {
    double sum = 0;
    for (std::size_t i = channel; i < mean.size(); i += 3) sum += mean[i];
    return sum / (mean.size() / 3);
  }
  // Standard error of image_mean: pixels are independent.
  double image_mean_standard_error(int channel) const {
    double sum = 0;
    for (std::size_t i = channel; i < variance.size(); i += 3) sum += variance[i] / samples;
    return std::sqrt(sum) / (variance.size() / 3);
  }
};

template <class T>
PixelStatistics sample_statistics(const FlatScene<T>& scene, u32 samples) {
  PixelStatistics stats;
  stats.width = scene.params.width;
  stats.height = scene.params.height;
  stats.samples = samples;
  const std::size_t pixels = static_cast<std::size_t>(stats.width) * stats.height;
  stats.mean.assign(3 * pixels, 0.0);
  stats.variance.assign(3 * pixels, 0.0);
  std::atomic<u64> non_finite{0};
  const SceneView<T> view = scene.view();
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  loop.run(stats.height, 1, [&](u32 y) {
      for (u32 x = 0; x < stats.width; ++x) {
        double mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
        u32 count = 0;
        for (u32 s = 0; s < samples; ++s) {
          const Color<T> c = trace_sample(view, x, y, s).radiance;
          if (!is_finite(c)) {
            ++non_finite;
            continue;
          }
          ++count;
          const double value[3] = {static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z)};
          for (int k = 0; k < 3; ++k) {  // Welford's update
            const double delta = value[k] - mean[k];
            mean[k] += delta / count;
            m2[k] += delta * (value[k] - mean[k]);
          }
        }
        const std::size_t i = 3 * (static_cast<std::size_t>(y) * stats.width + x);
        for (int k = 0; k < 3; ++k) {
          stats.mean[i + k] = mean[k];
          stats.variance[i + k] = count > 1 ? m2[k] / (count - 1) : 0.0;
        }
      }
  });
  stats.non_finite = non_finite;
  return stats;
}

// Reads a portable float map (colour "PF" only), returning rows from the top like LinearImage.
inline LinearImage read_pfm(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::string magic;
  long width = 0, height = 0;
  double scale = 0;
  in >> magic >> width >> height >> scale;
  if (!in || magic != "PF" || width <= 0 || height <= 0 || scale == 0) throw std::runtime_error("not a colour PFM: " + path.string());
  in.get();  // the single whitespace character that ends the header
  const bool little_endian = scale < 0;
  LinearImage image;
  image.width = static_cast<u32>(width);
  image.height = static_cast<u32>(height);
  image.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  std::vector<unsigned char> row(static_cast<std::size_t>(width) * 3 * 4);
  for (long r = height - 1; r >= 0; --r) {  // PFM stores the bottom row first
    in.read(reinterpret_cast<char*>(row.data()), static_cast<std::streamsize>(row.size()));
    if (!in) throw std::runtime_error("truncated PFM: " + path.string());
    for (std::size_t i = 0; i < static_cast<std::size_t>(width) * 3; ++i) {
      const unsigned char* b = &row[4 * i];
      const u32 bits = little_endian ? (u32(b[0]) | u32(b[1]) << 8 | u32(b[2]) << 16 | u32(b[3]) << 24)
                                     : (u32(b[3]) | u32(b[2]) << 8 | u32(b[1]) << 16 | u32(b[0]) << 24);
      float value;
      std::memcpy(&value, &bits, sizeof value);
      image.rgb[static_cast<std::size_t>(r) * width * 3 + i] = value;
    }
  }
  if (in.peek() != std::char_traits<char>::eof()) throw std::runtime_error("trailing bytes after the PFM data: " + path.string());
  return image;
}

// The stored reference image: scenes/tiny.json (64x48, max_depth 8) rendered at kReferenceSamples samples per pixel
// with seed kReferenceSeed, in double precision, by make_reference_image.cpp; beside it, the per-sample variance
// of every pixel and channel, estimated from the same samples.
inline constexpr u32 kReferenceSamples = 4096;
inline constexpr u32 kReferenceSeed = 20240601;
inline std::filesystem::path reference_image_path() { return source_dir() / "tests" / "data" / "tiny-reference.pfm"; }
inline std::filesystem::path reference_variance_path() { return source_dir() / "tests" / "data" / "tiny-reference-variance.pfm"; }

template <class T>
FlatScene<T> tiny_reference_scene(u32 samples, u32 seed) {
  SceneDescription scene = load_scene_file(scene_path("tiny.json"));
  scene.render.samples_per_pixel = samples;
  scene.render.seed = seed;
  return flatten<T>(scene);
}

// The output of one run of the command-line program.
struct CommandResult {
  int exit_code = -1;
  std::string err;  // everything it wrote to stderr
};

#ifdef PT_PATHTRACER_BINARY
// Runs `pathtracer ARGUMENTS` (arguments already quoted for the shell), capturing stderr in `folder`.
inline CommandResult run_pathtracer(const std::string& arguments, const TempDir& folder) {
  const std::filesystem::path err = folder / "stderr.txt";
  const char* moved = std::getenv("PT_PATHTRACER_BINARY");
  const std::string binary = moved && *moved ? moved : PT_PATHTRACER_BINARY;
  const std::string command = "'" + binary + "' " + arguments + " > /dev/null 2> '" + err.string() + "'";
  const int status = std::system(command.c_str());
  CommandResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.err = read_text_file(err);
  std::filesystem::remove(err);
  return result;
}
#endif

// A path quoted for the shell (the test folders' paths contain no quotes).
inline std::string quoted(const std::filesystem::path& path) {
  std::string out(1, '\'');
  out += path.string();
  out += '\'';
  return out;
}

// Lines of a text, without their line breaks.
inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// How close two renders of the same scene are: RMSE, both means, and the share of channels within 1e-3 relative.
struct ImagePair {
  double rmse = 0, mean_a = 0, mean_b = 0, close_fraction = 0;
};

inline ImagePair compare_images(const LinearImage& a, const LinearImage& b) {
  ImagePair out;
  double squared = 0;
  std::size_t close = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = static_cast<double>(a.rgb[i]) - b.rgb[i];
    squared += d * d;
    out.mean_a += a.rgb[i];
    out.mean_b += b.rgb[i];
    if (std::abs(d) <= 1e-3 * std::max(1.0, static_cast<double>(std::abs(a.rgb[i])))) ++close;
  }
  const double n = static_cast<double>(a.rgb.size());
  out.rmse = std::sqrt(squared / n);
  out.mean_a /= n;
  out.mean_b /= n;
  out.close_fraction = close / n;
  return out;
}

// A shipped scene's name as a test name ("book1-final" -> "book1_final").
inline std::string scene_test_name(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  for (char& c : name)
    if (c == '-') c = '_';
  return name;
}

}  // namespace pt::test
