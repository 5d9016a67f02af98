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
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <gtest/gtest.h>

#include "backends/cpu/cpu_backend.hpp"
#include "base/parallel_loop.hpp"
#include "film/film.hpp"
#include "flat/flat_scene.hpp"
#include "image/image_io.hpp"
#include "loading/model_files.hpp"
#include "loading/scene_loader.hpp"

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
      if (it->is_directory(error))
        std::filesystem::permissions(it->path(), std::filesystem::perms::owner_all, std::filesystem::perm_options::add, error);
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

// A P6 PPM image of width x height texels, each three bytes as given (read as they are: a normal map is linear data).
inline void write_ppm(const std::filesystem::path& path, u32 width, u32 height, const std::vector<u8>& rgb) {
  std::string text = "P6\n" + std::to_string(width) + " " + std::to_string(height) + "\n255\n";
  text.append(reinterpret_cast<const char*>(rgb.data()), rgb.size());
  write_text_file(path, text);
}

// Pearson's chi-square statistic of counts that should be uniform over their bins.
inline double chi_square(const std::vector<long>& counts, long total) {
  const double expected = static_cast<double>(total) / counts.size();
  double sum = 0;
  for (long c : counts) sum += (c - expected) * (c - expected) / expected;
  return sum;
}

// `text` with the first `from` replaced by `to`; a `from` that is not there is a mistake in the test.
inline std::string replaced(const std::string& text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("no '" + from + "' in the text");
  return text.substr(0, at) + to + text.substr(at + from.size());
}

inline constexpr double kPi = 3.14159265358979323846;

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

// A model file made in memory: `count` separate triangles in [-2, 2]^3 with edges of `size` (0.02 to 1,
// log-uniform, where 0), random normals and uvs, one default material and one placement.
inline std::shared_ptr<MeshFile> triangle_soup(TestRandom& rng, int count, double size = 0) {
  auto file = std::make_shared<MeshFile>();
  file->path = "generated.ply";
  TriangleMesh mesh;
  mesh.name = "soup";
  for (int i = 0; i < count; ++i) {
    const Vec3d p = rng.vec3(-2, 2);
    const double s = size > 0 ? size : 0.02 * std::pow(50.0, rng.uniform());
    const Vec3d a = rng.unit_vector();  // drawn in a fixed order
    const Vec3d b = rng.unit_vector();
    for (const Vec3d& v : {p, p + s * a, p + s * b}) {
      mesh.positions.push_back(v);
      mesh.normals.push_back(rng.unit_vector());
      const double u = rng.uniform();
      mesh.uvs.push_back({u, rng.uniform()});
    }
    const u32 first = static_cast<u32>(3 * i);
    mesh.triangles.push_back({first, first + 1, first + 2});
  }
  file->meshes.push_back(mesh);
  file->materials.push_back(MeshMaterial{});
  file->placements.push_back(MeshPlacement{0, AffineTransform{}});
  return file;
}

// A scene made in code, with nothing in it yet: the camera at `from`, looking at `at` and focused there.
inline SceneDescription generated_scene(const Vec3d& from, const Vec3d& at = {0, 0, 0}) {
  SceneDescription scene;
  scene.source = "generated";
  scene.camera.look_from = from;
  scene.camera.look_at = at;
  scene.camera.focus_distance = length(from - at);
  return scene;
}

// --- Checks of model files read by the mesh readers -----------------------------------------------------------

inline u64 triangle_count(const MeshFile& file) {
  u64 count = 0;
  for (const TriangleMesh& mesh : file.meshes) count += mesh.triangles.size();
  return count;
}

inline u64 vertex_count(const MeshFile& file) {
  u64 count = 0;
  for (const TriangleMesh& mesh : file.meshes) count += mesh.positions.size();
  return count;
}

// The bounds, in the file's space, of every vertex a triangle uses, at every place the file puts its mesh.
inline std::pair<Vec3d, Vec3d> placed_bounds(const MeshFile& file) {
  const double inf = std::numeric_limits<double>::infinity();
  Vec3d lo{inf, inf, inf}, hi{-inf, -inf, -inf};
  for (const MeshPlacement& placement : file.placements) {
    const TriangleMesh& mesh = file.meshes.at(placement.mesh);
    for (const auto& triangle : mesh.triangles)
      for (const u32 index : triangle) {
        const Vec3d q = placement.transform.apply_point(mesh.positions.at(index));
        lo = vmin(lo, q);
        hi = vmax(hi, q);
      }
  }
  return {lo, hi};
}

inline void expect_near(const Vec3d& a, const Vec3d& b, double tolerance) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

inline void expect_placed_bounds(const MeshFile& file, const Vec3d& lo, const Vec3d& hi, double tolerance) {
  const auto [got_lo, got_hi] = placed_bounds(file);
  expect_near(got_lo, lo, tolerance);
  expect_near(got_hi, hi, tolerance);
}

// What every file read must satisfy: each index names a vertex of its mesh, per-vertex arrays have one entry per
// position, positions are finite and normals of unit length, and materials, textures and placements are valid.
inline void expect_consistent(const MeshFile& file, double normal_tolerance = 1e-9) {
  ASSERT_FALSE(file.materials.empty());
  for (const TriangleMesh& mesh : file.meshes) {
    EXPECT_TRUE(mesh.normals.empty() || mesh.normals.size() == mesh.positions.size()) << mesh.name;
    EXPECT_TRUE(mesh.uvs.empty() || mesh.uvs.size() == mesh.positions.size()) << mesh.name;
    EXPECT_TRUE(mesh.materials.empty() || mesh.materials.size() == mesh.triangles.size()) << mesh.name;
    for (const auto& triangle : mesh.triangles)
      for (const u32 index : triangle) ASSERT_LT(index, mesh.positions.size()) << mesh.name;
    for (const u32 material : mesh.materials) ASSERT_LT(material, file.materials.size()) << mesh.name;
    for (const Vec3d& p : mesh.positions) ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << mesh.name;
    for (const Vec3d& n : mesh.normals) ASSERT_NEAR(length(n), 1.0, normal_tolerance) << mesh.name;
  }
  for (const MeshPlacement& placement : file.placements) ASSERT_LT(placement.mesh, file.meshes.size());
  for (const MeshMaterial& material : file.materials) {
    EXPECT_LT(material.base_color_texture, static_cast<i32>(file.textures.size()));
    EXPECT_LT(material.emission_texture, static_cast<i32>(file.textures.size()));
  }
}

inline bool has_warning(const MeshFile& file, const std::string& part) {
  return std::any_of(file.warnings.begin(), file.warnings.end(), [&](const std::string& w) { return w.find(part) != std::string::npos; });
}

inline std::string all_warnings(const MeshFile& file) {
  std::string text;
  for (const std::string& warning : file.warnings) text += warning + "\n";
  return text;
}

// Reading `path` must throw one InputError: one line, starting with the file's name, holding each of `parts` (the
// place in the file and what is wrong). Returns the message.
inline std::string expect_refused(const std::filesystem::path& path, const std::vector<std::string>& parts) {
  try {
    const MeshFile file = read_mesh_file(path);
    ADD_FAILURE() << path << " was read (" << triangle_count(file) << " triangles)";
    return {};
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_TRUE(message.starts_with(path.string() + ":")) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    for (const std::string& part : parts) EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
    return message;
  }
}

// Places a model file of the scene by scale, then rotation (degrees about x, y, z), then translation.
inline void place_mesh(SceneDescription& scene, u32 file, const Vec3d& scale, const Vec3d& degrees, const Vec3d& at, u32 material = kMeshMaterials) {
  SceneObject o;
  o.shape = MeshSettings{file, AffineTransform::scaling(scale).then(AffineTransform::from_rigid(RigidTransform::from_euler_degrees(degrees, at)))};
  o.material = material;
  scene.objects.push_back(o);
}

template <class T>
Vec3<T> to(const Vec3d& v) {
  return {static_cast<T>(v.x), static_cast<T>(v.y), static_cast<T>(v.z)};
}

// Parses scene text as if it were a file in scenes/ (so image paths such as textures/... resolve).
inline SceneDescription parse(const std::string& json, const std::string& source = "test.json") { return parse_scene(json, source, scenes_dir()); }

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

// Whether two films hold the same sums bit for bit, and the same sample and ray counts and stops.
inline bool same_film(const std::vector<FilmPixel>& a, const std::vector<FilmPixel>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(&a[i].r, &b[i].r, sizeof(double)) || std::memcmp(&a[i].g, &b[i].g, sizeof(double)) ||
        std::memcmp(&a[i].b, &b[i].b, sizeof(double)) || std::memcmp(&a[i].first_brightness, &b[i].first_brightness, sizeof(float)) ||
        a[i].samples != b[i].samples || a[i].rays != b[i].rays || a[i].stopped_at != b[i].stopped_at)
      return false;
  return true;
}

// Mean and variance (of one sample) of every pixel's finite samples, channel by channel, computed from the
// individual samples of the integrator (the film only keeps sums).
struct PixelStatistics {
  u32 width = 0, height = 0, samples = 0;
  std::vector<double> mean;      // 3 per pixel
  std::vector<double> variance;  // 3 per pixel, unbiased
  u64 non_finite = 0;

  // Statistics of a width x height image, every value zero.
  static PixelStatistics zeros(u32 width, u32 height, u32 samples) {
    PixelStatistics stats;
    stats.width = width;
    stats.height = height;
    stats.samples = samples;
    stats.mean.assign(3 * static_cast<std::size_t>(width) * height, 0.0);
    stats.variance.assign(stats.mean.size(), 0.0);
    return stats;
  }
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

// The statistics of `samples` samples of every pixel, traced by the kernel's own path function (trace_sample) on all
// the host's threads. Compiled once, with the libraries' optimisation, in test_support.cpp (float and double).
template <class T>
PixelStatistics sample_statistics(const FlatScene<T>& scene, u32 samples);
extern template PixelStatistics sample_statistics<float>(const FlatScene<float>&, u32);
extern template PixelStatistics sample_statistics<double>(const FlatScene<double>&, u32);

// The same statistics from any backend, through its interface only: each sample of every pixel is rendered in a
// call of its own, and its value is the difference of the film's sums before and after (sums in double, so the
// difference loses nothing that matters: at most about 1e-16 of the sum). A non-finite sample leaves the pixel's
// count unchanged and is left out, as the film does. The film sums float samples in double on every backend, so
// this works for GPU backends as well as the CPU.
template <class T>
PixelStatistics backend_sample_statistics(RenderBackend<T>& backend, const FlatScene<T>& scene, u32 samples) {
  PixelStatistics stats = PixelStatistics::zeros(scene.params.width, scene.params.height, samples);
  const std::size_t pixels = static_cast<std::size_t>(stats.width) * stats.height;
  // stats.variance holds the sums of squared deviations until the end.
  std::vector<u32> counts(pixels, 0);
  std::vector<FilmPixel> before(pixels, FilmPixel{}), after;
  backend.upload(scene);
  for (u32 s = 0; s < samples; ++s) {
    backend.render(s, 1);
    backend.read_film(after);
    if (after.size() != pixels) throw std::runtime_error("the film has the wrong size");
    for (std::size_t p = 0; p < pixels; ++p) {
      if (after[p].samples == before[p].samples) {
        ++stats.non_finite;
        continue;
      }
      const u32 count = ++counts[p];
      const double value[3] = {after[p].r - before[p].r, after[p].g - before[p].g, after[p].b - before[p].b};
      for (int k = 0; k < 3; ++k) {  // Welford's update
        double& mean = stats.mean[3 * p + k];
        const double delta = value[k] - mean;
        mean += delta / count;
        stats.variance[3 * p + k] += delta * (value[k] - mean);
      }
    }
    std::swap(before, after);
  }
  for (std::size_t p = 0; p < pixels; ++p)
    for (int k = 0; k < 3; ++k) stats.variance[3 * p + k] = counts[p] > 1 ? stats.variance[3 * p + k] / (counts[p] - 1) : 0.0;
  return stats;
}

// One channel of one square block of pixels, in two renders of the same scene: the block means, the standard
// deviation of their difference were the renders independent, and the z-score of the difference.
struct BlockDifference {
  u32 x = 0, y = 0;  // the block's top-left pixel
  int channel = 0;
  double mean_a = 0, mean_b = 0;
  double sigma = 0;  // sqrt(var(mean_a) + var(mean_b))
  double z = 0;      // |mean_a - mean_b| / sigma (infinite for a difference where both variances are 0)
  bool within = true;
};

// The block means of two renders may differ by noise only: for a block of n pixels rendered with N samples each,
// var(block mean) = sum over its pixels of (per-sample variance / N) / n^2, for each render; a difference is within
// when |mean_a - mean_b| <= k sqrt(var_a + var_b) + floor, the floor being absolute_floor + relative_floor * the
// larger mean (for blocks whose samples are all alike, where the two scalar types still round differently).
// Returns every block and channel, the worst (largest |difference| / allowed) first.
inline std::vector<BlockDifference> compare_block_means(const PixelStatistics& a, const PixelStatistics& b, u32 block, double k,
                                                        double absolute_floor, double relative_floor) {
  if (a.width != b.width || a.height != b.height) throw std::runtime_error("the renders differ in size");
  std::vector<BlockDifference> blocks;
  std::vector<double> excess;
  for (u32 by = 0; by < a.height; by += block)
    for (u32 bx = 0; bx < a.width; bx += block)
      for (int c = 0; c < 3; ++c) {
        double sum_a = 0, sum_b = 0, var_a = 0, var_b = 0;
        u32 n = 0;
        for (u32 y = by; y < std::min(by + block, a.height); ++y)
          for (u32 x = bx; x < std::min(bx + block, a.width); ++x) {
            const std::size_t i = 3 * (static_cast<std::size_t>(y) * a.width + x) + c;
            sum_a += a.mean[i];
            sum_b += b.mean[i];
            var_a += a.variance[i] / a.samples;
            var_b += b.variance[i] / b.samples;
            ++n;
          }
        BlockDifference d;
        d.x = bx;
        d.y = by;
        d.channel = c;
        d.mean_a = sum_a / n;
        d.mean_b = sum_b / n;
        d.sigma = std::sqrt(var_a + var_b) / n;
        const double difference = std::abs(d.mean_a - d.mean_b);
        d.z = d.sigma > 0 ? difference / d.sigma : (difference > 0 ? std::numeric_limits<double>::infinity() : 0.0);
        const double allowed = k * d.sigma + absolute_floor + relative_floor * std::max(std::abs(d.mean_a), std::abs(d.mean_b));
        d.within = difference <= allowed;
        blocks.push_back(d);
        excess.push_back(difference / allowed);
      }
  std::vector<std::size_t> order(blocks.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return excess[i] > excess[j]; });
  std::vector<BlockDifference> sorted;
  for (std::size_t i : order) sorted.push_back(blocks[i]);
  return sorted;
}

// The first `count` blocks of compare_block_means, one line each, for a failure message.
inline std::string describe_blocks(const std::vector<BlockDifference>& blocks, std::size_t count, const char* name_a, const char* name_b) {
  std::ostringstream out;
  out.precision(5);
  for (std::size_t i = 0; i < std::min(count, blocks.size()); ++i) {
    const BlockDifference& d = blocks[i];
    out << "  block at (" << d.x << ", " << d.y << ") "
        << "RGB"[d.channel] << ": " << name_a << " " << d.mean_a << ", " << name_b << " " << d.mean_b << ", difference " << d.mean_a - d.mean_b
        << " (" << (d.mean_b != 0 ? 100 * (d.mean_a - d.mean_b) / d.mean_b : 0.0) << "%), sigma " << d.sigma << ", z " << d.z
        << (d.within ? "" : "  OUTSIDE") << "\n";
  }
  return out.str();
}

// Moving or scaling a scene changes the pattern of a texture that reads the world position (checker, noise): such
// scenes are refused by the helpers below.
inline void require_position_free_textures(const SceneDescription& scene, const char* who) {
  for (const Texture<double>& t : scene.textures)
    if (std::holds_alternative<CheckerTexture<double>>(t) || std::holds_alternative<NoiseTexture<double>>(t))
      throw std::runtime_error(std::string(who) + ": the scene has a texture that depends on the world position");
}

// The scene moved by `offset`: every object (a medium's boundary follows its object's transform) and the camera.
// Textures that read the world position (checker, noise) would move their pattern relative to the geometry, so a
// scene with them is refused.
inline SceneDescription translated(SceneDescription scene, const Vec3d& offset) {
  require_position_free_textures(scene, "translated()");
  RigidTransform move;
  move.translation = offset;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject object = scene.objects[i];
    object.transform = object.transform.then(move);
    scene.objects.set(i, object);
  }
  scene.camera.look_from = scene.camera.look_from + offset;
  scene.camera.look_at = scene.camera.look_at + offset;
  return scene;
}

// The scene as if it had been modelled `factor` times larger (or smaller): every position, size and translation
// multiplied, densities divided, the camera moved with it. Unlike flatten_scene's scale, nothing else follows: a
// setting of a fixed size stays as it was, as it would in a file written at the other scale.
inline SceneDescription scaled(SceneDescription scene, double factor) {
  require_position_free_textures(scene, "scaled()");
  struct Scale {
    double f;
    void operator()(Sphere<double>& x) const { x = Sphere<double>{x.center * f, x.radius * f}; }
    void operator()(MovingSphereSettings& x) const {
      x.center0 = x.center0 * f;
      x.center1 = x.center1 * f;
      x.radius *= f;
    }
    void operator()(TriangleSettings& x) const {
      for (Vec3d& v : x.vertices) v = v * f;
    }
    void operator()(QuadSettings& x) const { x = QuadSettings{x.corner * f, x.u * f, x.v * f}; }
    void operator()(BoxSettings& x) const { x = BoxSettings{x.min * f, x.max * f}; }
    void operator()(MediumSettings& x) const {
      if (auto* sphere = std::get_if<Sphere<double>>(&x.boundary)) (*this)(*sphere);
      if (auto* box = std::get_if<BoxSettings>(&x.boundary)) (*this)(*box);
      x.boundary_transform.translation = x.boundary_transform.translation * f;
      x.density /= f;
    }
    void operator()(MeshSettings& x) const { x.transform = x.transform.then(AffineTransform::scaling({f, f, f})); }
  };
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject object = scene.objects[i];
    std::visit(Scale{factor}, object.shape);
    object.transform.translation = object.transform.translation * factor;
    scene.objects.set(i, object);
  }
  scene.camera.look_from = scene.camera.look_from * factor;
  scene.camera.look_at = scene.camera.look_at * factor;
  scene.camera.focus_distance *= factor;
  scene.camera.aperture *= factor;
  return scene;
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
// The program: where it was built, unless PT_PATHTRACER_BINARY in the environment says it moved.
inline std::string pathtracer_binary() {
  const char* moved = std::getenv("PT_PATHTRACER_BINARY");
  return moved && *moved ? moved : PT_PATHTRACER_BINARY;
}

// Runs `pathtracer ARGUMENTS` (arguments already quoted for the shell), capturing stderr in `folder`.
inline CommandResult run_pathtracer(const std::string& arguments, const TempDir& folder) {
  const std::filesystem::path err = folder / "stderr.txt";
  const std::string command = "'" + pathtracer_binary() + "' " + arguments + " > /dev/null 2> '" + err.string() + "'";
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

// Whether `other` (another backend's render with the seed of `cpu`) shares nearly all of its samples with the CPU's:
// much closer to it than a CPU render of another seed (RMSE at most a quarter), the same mean within 0.5 %, and at
// least 90 % of channels within 1e-3. Why not bitwise: tests/test_backend_parity.cpp.
inline void expect_same_samples_as_the_cpu(const LinearImage& cpu, const LinearImage& other, const LinearImage& cpu_other_seed,
                                           const std::string& label) {
  const ImagePair same = compare_images(cpu, other);
  const ImagePair independent = compare_images(cpu, cpu_other_seed);
  std::printf("%s: rmse against the CPU %.3g, CPU against another seed %.3g, means %.6f / %.6f, channels within 1e-3: %.1f%%\n", label.c_str(),
              same.rmse, independent.rmse, same.mean_a, same.mean_b, 100 * same.close_fraction);
  EXPECT_LE(same.rmse, 0.25 * independent.rmse) << label << ": same-seed images should share nearly all samples";
  EXPECT_NEAR(same.mean_a, same.mean_b, 5e-3 * std::max(same.mean_a, 1e-3)) << label;
  EXPECT_GE(same.close_fraction, 0.90) << label;
}

// The SYCL device the tests use: PT_TEST_SYCL_DEVICE when set (an index of `pathtracer devices`), else the runtime's
// default choice (negative).
inline int sycl_test_device() {
  const char* chosen = std::getenv("PT_TEST_SYCL_DEVICE");
  return chosen ? std::atoi(chosen) : -1;
}

// A shipped scene's name as a test name ("book1-final" -> "book1_final").
inline std::string scene_test_name(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  for (char& c : name)
    if (c == '-') c = '_';
  return name;
}

}  // namespace pt::test
