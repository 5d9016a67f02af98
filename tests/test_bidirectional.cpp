// Bidirectional path tracing has the path tracer's expected image on every shipped scene, leaves less noise where
// light reaches diffuse surfaces through glass or off mirrors, makes the same image whatever the threads and passes,
// and refuses, with one line, what it cannot do. Vertex merging (vcm) converges to the same image, leaves less noise
// still where those caustics are seen through glass, and is as reproducible.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "backends/cpu/cpu_backend.hpp"
#include "backends/registry.hpp"
#include "film/film.hpp"
#include "kernel/bidirectional.hpp"
#include "scene_cases.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt {
namespace {

// How each scene is rendered here: the shipped scenes of the statistical suite as it renders them (fewer samples
// for the costly Cornell box, whose paths are cut at 5 bounces there), and the scenes with caustics, whose path
// tracer images are noisy enough that 256 samples of a small image are needed for a bound that means anything. There
// the path tracer takes 4 times the samples: it finds a caustic on rare samples only, and a variance estimated from too
// few of them falls short of the truth (at 256 samples a block of the caustics scene stood at z = 5.9; at 16,384 the
// two agreed within 0.8 %).
struct BidirectionalCase {
  const char* name;
  u32 width, height, samples, max_depth;
  u32 path_factor = 1;  // the path tracer's samples over bdpt's
};

const BidirectionalCase& bidirectional_case(const std::string& name) {
  static const std::vector<BidirectionalCase> cases = {
      {"tiny", 64, 48, 128, 0},         {"meshes", 64, 48, 64, 0},        {"seed-default", 64, 48, 64, 0},   {"book1-final", 64, 48, 64, 0},
      {"book2-final", 48, 48, 64, 0},   {"cornell-box", 48, 48, 256, 5},  {"cornell-smoke", 48, 48, 64, 0},  {"environment", 64, 48, 64, 0},
      {"normal-maps", 64, 48, 64, 0},   {"caustics", 48, 32, 256, 8, 4},  {"cornell-glass", 48, 48, 256, 8, 4}, {"light-through-gap", 48, 32, 256, 8, 4},
  };
  for (const BidirectionalCase& c : cases)
    if (name == c.name) return c;
  throw std::runtime_error("no settings for scene " + name);
}

RenderSettings settings_for(const SceneDescription& scene, const BidirectionalCase& c, u32 samples, u32 seed) {
  RenderSettings settings = scene.render;
  settings.width = c.width;
  settings.height = c.height;
  settings.samples_per_pixel = samples;
  if (c.max_depth) settings.max_depth = c.max_depth;
  settings.seed = seed;
  return settings;
}

template <class T>
std::unique_ptr<RenderBackend<T>> backend_named(const std::string& name, Integrator integrator) {
  return make_backend<T>(name, 0, 0, integrator, name == "sycl" ? test::sycl_test_device() : -1);
}

template <class T>
test::PixelStatistics statistics(const std::string& backend_name, Integrator integrator, const FlatScene<T>& flat) {
  const std::unique_ptr<RenderBackend<T>> backend = backend_named<T>(backend_name, integrator);
  return test::backend_sample_statistics(*backend, flat, flat.samples_per_pixel);
}

// Why a GPU test cannot run here, or empty when it can.
std::string why_no(const std::string& backend) {
  if (backend == "cuda") {
#if !PT_HAVE_CUDA
    return "the CUDA backend is not built (no nvcc)";
#else
    if (cuda_device_count() == 0) return "no usable GPU on this machine";
#endif
  }
  if (backend == "sycl") {
#if !PT_HAVE_SYCL
    return "the SYCL backend is not built (configure with -DPT_SYCL=ON)";
#endif
  }
  return {};
}

// Both in float, with independent seeds; `factor` multiplies the case's samples.
void expect_bidirectional_matches_path_tracer(const std::string& name, const std::string& backend, u32 factor,
                                              Integrator integrator = Integrator::kBidirectional) {
  const SceneDescription scene = load_scene_file(test::scene_path(name + ".json"));
  const BidirectionalCase& c = bidirectional_case(name);
  const u32 samples = c.samples * factor / test::kSampleDivisor;
  const test::PixelStatistics bdpt = statistics<float>(backend, integrator, flatten_scene<float>(scene, settings_for(scene, c, samples, 909)));
  const test::PixelStatistics path =
      statistics<float>(backend, Integrator::kMegakernel, flatten_scene<float>(scene, settings_for(scene, c, samples * c.path_factor, 919)));
  EXPECT_EQ(bdpt.non_finite, 0u);
  test::expect_blocks_agree(bdpt, path, integrator_name(integrator), "path", name + " (" + backend + ")");
}

class BidirectionalMatchesPathTracer : public ::testing::TestWithParam<std::string> {};

TEST_P(BidirectionalMatchesPathTracer, BlockMeansAgreeWithinNoise) { expect_bidirectional_matches_path_tracer(GetParam(), "cpu", 1); }

// At 8 times the samples, where a bias of a fraction of a percent would show: on a GPU.
TEST_P(BidirectionalMatchesPathTracer, CudaBlockMeansAgreeAtHighSampleCounts) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_matches_path_tracer(GetParam(), "cuda", 8);
}

// The same through SYCL (on its GPU where PT_TEST_SYCL_DEVICE names one, at the CPU's samples on a CPU device).
TEST_P(BidirectionalMatchesPathTracer, SyclBlockMeansAgreeWithinNoise) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_matches_path_tracer(GetParam(), "sycl", std::getenv("PT_TEST_SYCL_DEVICE") ? 8 : 1);
}

INSTANTIATE_TEST_SUITE_P(Scenes, BidirectionalMatchesPathTracer,
                         ::testing::Values("tiny", "meshes", "seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke",
                                           "environment", "normal-maps", "caustics", "cornell-glass", "light-through-gap"),
                         test::scene_test_name);

// Vertex merging is consistent, not unbiased: each pass blurs the light vertices over a disc that shrinks from a pixel's
// footprint as passes are added. Over the test's blocks of pixels that blur moves the mean by far less than the noise,
// so the blocks agree with the path tracer's within the same bounds; the scenes cover caustics (through glass and off
// a mirror), a medium (no merging there, its weights still right), meshes and the sky.
class VertexMergingMatchesPathTracer : public ::testing::TestWithParam<std::string> {};

TEST_P(VertexMergingMatchesPathTracer, BlockMeansAgreeWithinNoise) {
  expect_bidirectional_matches_path_tracer(GetParam(), "cpu", 1, Integrator::kVertexMerging);
}

TEST_P(VertexMergingMatchesPathTracer, CudaBlockMeansAgreeAtHighSampleCounts) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_matches_path_tracer(GetParam(), "cuda", 8, Integrator::kVertexMerging);
}

TEST_P(VertexMergingMatchesPathTracer, SyclBlockMeansAgreeWithinNoise) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_matches_path_tracer(GetParam(), "sycl", std::getenv("PT_TEST_SYCL_DEVICE") ? 8 : 1, Integrator::kVertexMerging);
}

INSTANTIATE_TEST_SUITE_P(Scenes, VertexMergingMatchesPathTracer,
                         ::testing::Values("tiny", "meshes", "cornell-box", "cornell-smoke", "caustics", "cornell-glass", "light-through-gap"),
                         test::scene_test_name);

// The mean of the per-sample variance over the image, channels summed: the noise one sample leaves.
double mean_variance(const test::PixelStatistics& stats) {
  double sum = 0;
  for (double v : stats.variance) sum += v;
  return sum / static_cast<double>(stats.variance.size());
}

// Where light reaches the floor through a glass sphere and off a ring's mirror wall, the path tracer finds it only
// when a path scatters into the small lamp; joining light subpaths to the camera finds it on every sample. Measured
// at 48x32 and 64 samples: per-sample variance about 10 times lower (BENCHMARKS.md).
TEST(Bidirectional, LeavesLessNoiseOnCausticsThanThePathTracer) {
  const SceneDescription scene = load_scene_file(test::scene_path("caustics.json"));
  const BidirectionalCase& c = bidirectional_case("caustics");
  // Not cut under the sanitizers: from a few samples the path tracer's variance, made of rare caustic samples, is
  // anybody's guess (0.3 times bdpt's from 4 samples).
  const u32 samples = 64;
  const test::PixelStatistics bdpt =
      statistics<float>("cpu", Integrator::kBidirectional, flatten_scene<float>(scene, settings_for(scene, c, samples, 31)));
  const test::PixelStatistics path = statistics<float>("cpu", Integrator::kMegakernel, flatten_scene<float>(scene, settings_for(scene, c, samples, 32)));
  const double ratio = mean_variance(path) / mean_variance(bdpt);
  std::printf("caustics: per-sample variance, path tracer / bdpt = %.1f\n", ratio);
  EXPECT_GT(ratio, 5.0);
}

// Inside a Lambertian sphere (radius R, albedo a) lit by a small lamp at its centre (radius rho, radiance E) every
// point of the wall receives the same light at every bounce, so the wall's radiance is a E rho^2 / (R^2 (1 - a)) (less
// about rho^2 / R^2 of it that the lamp hides), and a density estimate over a disc of any size has no bias there: the
// cap of a sphere within a chord r of a point has area pi r^2 exactly. Merging within a fifth of the sphere's radius
// then takes most of the weight, and the mean comes out right only if the weights of all strategies of every path sum
// to one (it fails with merging's share left out of the light subpaths' weights). Passes are independent (each takes
// light subpaths of its own), so the error of the mean is estimated from the spread of the passes' image means; the
// pixels of one pass share its light vertices and are not independent.
TEST(VertexMerging, InsideALitSphereTheWallHasItsAnalyticRadiance) {
  const std::string json = R"({
    "render": {"width": 48, "height": 48, "samples_per_pixel": 96, "max_depth": 50},
    "camera": {"look_from": [0, 0, -4], "look_at": [0, 0, -10], "vertical_fov": 60},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "sphere", "center": [0, 0, 0], "radius": 10, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.1, "material": {"type": "diffuse_light", "emission": [10000, 10000, 10000]}}
    ]})";
  const double expected = 0.5 * 10000 * 0.01 / (100 * (1 - 0.5));  // 1
  const SceneDescription scene = test::parse(json);
  // The path tracer, then merging over a tenth and a fortieth of the sphere's radius (merging then shares the weight
  // with the connections).
  for (const double radius : {0.0, 1.0, 0.25}) {
    RenderSettings settings = scene.render;
    settings.merge_radius = radius;
    const FlatScene<float> flat = flatten_scene<float>(scene, settings);
    const Integrator integrator = radius > 0 ? Integrator::kVertexMerging : Integrator::kMegakernel;
    const std::unique_ptr<RenderBackend<float>> backend = make_cpu_backend<float>(2, integrator);
    backend->upload(flat);
    std::vector<double> pass_means;
    std::vector<FilmPixel> before(48 * 48, FilmPixel{}), after;
    for (u32 s = 0; s < settings.samples_per_pixel; ++s) {
      backend->render(s, 1);
      backend->read_film(after);
      double sum = 0;
      for (std::size_t p = 0; p < after.size(); ++p) sum += (after[p].r - before[p].r) + (after[p].g - before[p].g) + (after[p].b - before[p].b);
      pass_means.push_back(sum / (3.0 * after.size()));
      std::swap(before, after);
    }
    double mean = 0, spread = 0;
    for (double m : pass_means) mean += m / pass_means.size();
    for (double m : pass_means) spread += (m - mean) * (m - mean) / (pass_means.size() - 1);
    const double error = std::sqrt(spread / pass_means.size());
    std::printf("%s (radius %g): wall radiance %.5f +- %.5f (analytic %.5f)\n", integrator_name(integrator), radius, mean, error, expected);
    EXPECT_LT(error, 0.01 * expected) << integrator_name(integrator);  // the test can see a bias of a few percent
    EXPECT_NEAR(mean, expected, 5 * error) << integrator_name(integrator);
  }
}

// Light that leaves a lamp only through glass and reaches the camera only through glass (lamp, glass, wall, glass,
// camera) has no connection at all: bdpt finds it only where a camera subpath scatters off the wall, through the glass,
// into the small lamp. Merging takes the light subpaths' wall vertices there. A lamp inside a glass ball at the centre
// of a Lambertian sphere, seen from inside another glass ball: per sample, merging leaves about three times less noise
// (the same without merging's share in the weights: merging then adds its own noise on top).
TEST(VertexMerging, LeavesLessNoiseThanBdptWhereLightAndCameraAreBehindGlass) {
  const std::string json = R"({
    "render": {"width": 32, "height": 32, "samples_per_pixel": 64, "max_depth": 12},
    "camera": {"look_from": [0, 0, -5], "look_at": [0, 0, -10], "vertical_fov": 60},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "sphere", "center": [0, 0, 0], "radius": 10, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.1, "material": {"type": "diffuse_light", "emission": [10000, 10000, 10000]}},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": {"type": "dielectric", "ior": 1.5}},
      {"type": "sphere", "center": [0, 0, -5], "radius": 0.5, "material": {"type": "dielectric", "ior": 1.5}}
    ]})";
  RenderSettings settings = test::parse(json).render;
  settings.merge_radius = 0.5;
  const FlatScene<float> flat = flatten_scene<float>(test::parse(json), settings);
  const double bdpt = mean_variance(statistics<float>("cpu", Integrator::kBidirectional, flat));
  const double vcm = mean_variance(statistics<float>("cpu", Integrator::kVertexMerging, flat));
  std::printf("behind glass: per-sample variance, bdpt / vcm = %.2f\n", bdpt / vcm);
  EXPECT_GT(bdpt / vcm, 2.0);
}

// A pane of glass before the camera reflects a large lamp behind it (Schlick's 4 %) and lets the black beyond through:
// nothing else lights anything, so every strategy but the camera subpath's own (s = 0) is empty. Choosing a way at the
// glass, as the path tracer does, sees the lamp on one sample in twenty-five at full brightness; the camera subpath
// splits what it meets next between both ways, so every sample sees the reflection at 4 % (its variance comes only from
// the angle's change over a pixel). Same mean, per-sample variance orders of magnitude lower (about 1 without the split).
TEST(Bidirectional, SeesALampInGlassOnEverySample) {
  const std::string json = R"({
    "render": {"width": 24, "height": 24, "samples_per_pixel": 64, "max_depth": 8},
    "camera": {"look_from": [0, 0, -5], "look_at": [0, 0, 0], "vertical_fov": 30},
    "background": {"type": "constant", "color": [0, 0, 0]},
    "objects": [
      {"type": "quad", "corner": [-3, -3, 0], "u": [6, 0, 0], "v": [0, 6, 0], "material": {"type": "dielectric", "ior": 1.5}},
      {"type": "quad", "corner": [-20, -20, -8], "u": [40, 0, 0], "v": [0, 40, 0], "material": {"type": "diffuse_light", "emission": [10, 10, 10]}}
    ]})";
  const SceneDescription scene = test::parse(json);
  const FlatScene<float> flat = flatten_scene<float>(scene, scene.render);
  const test::PixelStatistics bdpt = statistics<float>("cpu", Integrator::kBidirectional, flat);
  const test::PixelStatistics path = statistics<float>("cpu", Integrator::kMegakernel, flat);
  double bdpt_mean = 0, path_mean = 0;
  for (double v : bdpt.mean) bdpt_mean += v / static_cast<double>(bdpt.mean.size());
  for (double v : path.mean) path_mean += v / static_cast<double>(path.mean.size());
  // The path tracer's image mean has the standard error of all its samples together.
  const double path_error = std::sqrt(mean_variance(path) / (static_cast<double>(path.mean.size()) * path.samples));
  std::printf("lamp in glass: image mean bdpt %.5f, path tracer %.5f +- %.5f; per-sample variance, path tracer / bdpt = %.3g\n", bdpt_mean, path_mean,
              path_error, mean_variance(path) / mean_variance(bdpt));
  EXPECT_NEAR(bdpt_mean, 0.04 * 10, 0.01);  // Schlick's reflectance near normal incidence: 4 % of the lamp
  EXPECT_NEAR(bdpt_mean, path_mean, 5 * path_error);
  EXPECT_GT(mean_variance(path) / mean_variance(bdpt), 100.0);
}

// Splats are summed as integers and folded into the film sample by sample: the film is the same bit for bit on one
// thread in one pass as on two threads in passes of 1 and 3 samples.
TEST(Bidirectional, ImagesDoNotDependOnThreadsOrPasses) {
  for (const char* name : {"caustics", "cornell-smoke", "tiny"}) {
    const SceneDescription scene = load_scene_file(test::scene_path(std::string(name) + ".json"));
    RenderSettings settings = scene.render;
    settings.width = 40;
    settings.height = 30;
    settings.samples_per_pixel = 4;
    const FlatScene<float> flat = flatten_scene<float>(scene, settings);
    for (const Integrator integrator : {Integrator::kBidirectional, Integrator::kVertexMerging}) {
      const std::vector<FilmPixel> one = test::render_film(flat, 1, {4}, integrator);
      const std::vector<FilmPixel> two = test::render_film(flat, 2, {1, 3}, integrator);
      EXPECT_TRUE(test::same_film(one, two)) << name << " (" << integrator_name(integrator) << ")";
    }
  }
}

// The same on a GPU, where thousands of threads add splats in an order that changes from run to run: the film of
// one pass of 4 samples is the film of passes of 1 and 3, bit for bit.
void expect_images_independent_of_passes(const std::string& backend_name, Integrator integrator = Integrator::kBidirectional) {
  for (const char* name : {"caustics", "cornell-smoke"}) {
    const SceneDescription scene = load_scene_file(test::scene_path(std::string(name) + ".json"));
    RenderSettings settings = scene.render;
    settings.width = 160;
    settings.height = 90;
    const FlatScene<float> flat = flatten_scene<float>(scene, settings);
    std::vector<std::vector<FilmPixel>> films;
    for (const std::vector<u32>& passes : {std::vector<u32>{4}, std::vector<u32>{1, 3}}) {
      const std::unique_ptr<RenderBackend<float>> backend = backend_named<float>(backend_name, integrator);
      backend->upload(flat);
      u32 first = 0;
      for (u32 count : passes) {
        backend->render(first, count);
        first += count;
      }
      films.emplace_back();
      backend->read_film(films.back());
    }
    EXPECT_TRUE(test::same_film(films[0], films[1])) << name << " (" << backend_name << ", " << integrator_name(integrator) << ")";
  }
}

TEST(Bidirectional, CudaImagesDoNotDependOnPasses) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_images_independent_of_passes("cuda");
}

TEST(Bidirectional, SyclImagesDoNotDependOnPasses) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_images_independent_of_passes("sycl");
}

// Vertex merging's grid is filled by threads in any order and each cell's list sorted: the film is as reproducible.
TEST(VertexMerging, CudaImagesDoNotDependOnPasses) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_images_independent_of_passes("cuda", Integrator::kVertexMerging);
}

TEST(VertexMerging, SyclImagesDoNotDependOnPasses) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_images_independent_of_passes("sycl", Integrator::kVertexMerging);
}

// The GPU runs the CPU's estimator sample for sample: with the same seed the two images share nearly every sample
// (test::expect_same_samples_as_the_cpu).
void expect_bidirectional_shares_the_cpus_samples(const std::string& backend_name) {
  for (const char* name : {"caustics", "cornell-glass", "cornell-smoke", "meshes"}) {
    const SceneDescription scene = load_scene_file(test::scene_path(std::string(name) + ".json"));
    RenderSettings settings = scene.render;
    settings.width = 64;
    settings.height = 48;
    settings.samples_per_pixel = 16;
    settings.max_depth = std::min<u32>(settings.max_depth, 8);
    auto render = [&](const std::string& backend, u32 seed) {
      RenderSettings seeded = settings;
      seeded.seed = seed;
      const std::unique_ptr<RenderBackend<float>> renderer = backend_named<float>(backend, Integrator::kBidirectional);
      return render_scene(*renderer, flatten_scene<float>(scene, seeded)).image;
    };
    test::expect_same_samples_as_the_cpu(render("cpu", 5), render(backend_name, 5), render("cpu", 6), std::string(name) + " (" + backend_name + ")");
  }
}

TEST(Bidirectional, CudaImagesShareTheCpusSamples) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_shares_the_cpus_samples("cuda");
}

TEST(Bidirectional, SyclImagesShareTheCpusSamples) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_bidirectional_shares_the_cpus_samples("sycl");
}

// The staged schedule (both subpaths, then the connections as a launch of their own, then the gathering, over bands of
// rows) forms each sample's sums in the one-kernel schedule's order: the same film bit for bit. On the CPU a band of
// the host's size holds a few rows of these images, so the bands' seams are crossed many times.
void expect_schedules_make_the_same_film(const std::string& backend_name, u32 width, u32 height, Integrator integrator = Integrator::kBidirectional) {
  for (const char* name : {"caustics", "cornell-smoke", "meshes", "environment", "seed-default"}) {
    const SceneDescription scene = load_scene_file(test::scene_path(std::string(name) + ".json"));
    RenderSettings settings = scene.render;
    settings.width = width;
    settings.height = height;
    settings.samples_per_pixel = 3;
    auto film = [&](BidirectionalSchedule schedule) {
      settings.bidirectional_schedule = schedule;
      const FlatScene<float> flat = flatten_scene<float>(scene, settings);  // the CPU renders from its arrays
      const std::unique_ptr<RenderBackend<float>> backend = backend_named<float>(backend_name, integrator);
      backend->upload(flat);
      backend->render(0, 2);
      backend->render(2, 1);
      std::vector<FilmPixel> pixels;
      backend->read_film(pixels);
      return pixels;
    };
    const std::vector<FilmPixel> one_kernel = film(BidirectionalSchedule::kOneKernel);
    const std::vector<FilmPixel> staged = film(BidirectionalSchedule::kStaged);
    EXPECT_TRUE(test::same_film(one_kernel, staged)) << name << " (" << backend_name << ", " << integrator_name(integrator) << ")";
  }
}

TEST(Bidirectional, StagedScheduleMakesTheOneKernelFilmBitForBit) { expect_schedules_make_the_same_film("cpu", 96, 64); }

// Merging's camera side in one launch (the host's default) or in stages: the same film too.
TEST(VertexMerging, StagedScheduleMakesTheOneLaunchFilmBitForBit) { expect_schedules_make_the_same_film("cpu", 96, 64, Integrator::kVertexMerging); }

TEST(VertexMerging, CudaStagedScheduleMakesTheOneLaunchFilmBitForBit) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_schedules_make_the_same_film("cuda", 320, 180, Integrator::kVertexMerging);
}

TEST(Bidirectional, CudaStagedScheduleMakesTheOneKernelFilmBitForBit) {
  if (const std::string why = why_no("cuda"); !why.empty()) GTEST_SKIP() << why;
  expect_schedules_make_the_same_film("cuda", 320, 180);
}

TEST(Bidirectional, SyclStagedScheduleMakesTheOneKernelFilmBitForBit) {
  if (const std::string why = why_no("sycl"); !why.empty()) GTEST_SKIP() << why;
  expect_schedules_make_the_same_film("sycl", 320, 180);
}

// The command line's --bdpt-schedule reaches the integrator: both schedules write the same file, the staged one runs its
// launches, and an unknown one is refused.
TEST(Bidirectional, CommandLineSchedulesWriteTheSameImage) {
  test::TempDir folder;
  auto render = [&](const std::string& schedule, const std::string& file) {
    return test::run_pathtracer("render " + test::quoted(test::scene_path("caustics.json")) + " --quiet --integrator bdpt --bdpt-schedule " + schedule +
                                    " --spp 2 --width 40 --height 24 -o " + test::quoted(folder / file),
                                folder);
  };
  ASSERT_EQ(render("one-kernel", "one.pfm").exit_code, 0);
  ASSERT_EQ(render("staged", "staged.pfm").exit_code, 0);
  EXPECT_EQ(test::read_text_file(folder / "one.pfm"), test::read_text_file(folder / "staged.pfm"));
  // The schedule asked for is the one run: bench names the launches it timed.
  const std::string bench = "'" + test::pathtracer_binary() + "' bench " + test::quoted(test::scene_path("caustics.json")) +
                            " --integrator bdpt --bdpt-schedule staged --spp 1 --width 16 --height 8 --runs 1 > " + test::quoted(folder / "bench.txt");
  ASSERT_EQ(std::system(bench.c_str()), 0);
  const std::string summary = test::read_text_file(folder / "bench.txt");
  EXPECT_NE(summary.find("connections"), std::string::npos) << summary;
  const test::CommandResult unknown = render("twice", "twice.pfm");
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.err.find("--bdpt-schedule"), std::string::npos) << unknown.err;
  EXPECT_FALSE(std::filesystem::exists(folder / "twice.pfm"));
}

// `numerics --bdpt` measures bidirectional path tracing: its Q32.32 image is the one `render --integrator bdpt` writes in
// Q32.32 with the same settings, byte for byte (without the flag it is the path tracer's, another image).
TEST(Bidirectional, NumericsMeasuresTheBidirectionalImage) {
  test::TempDir folder;
  const std::string scene = test::quoted(test::scene_path("caustics.json"));
  const std::string size = " --spp 2 --width 40 --height 24";
  ASSERT_EQ(test::run_pathtracer("numerics " + scene + " --bdpt --formats q32.32" + size + " -o " + test::quoted(folder / "bdpt"), folder).exit_code, 0);
  ASSERT_EQ(test::run_pathtracer("numerics " + scene + " --formats q32.32" + size + " -o " + test::quoted(folder / "path"), folder).exit_code, 0);
  ASSERT_EQ(test::run_pathtracer("render " + scene + " --quiet --integrator bdpt --number-format q32.32" + size + " -o " + test::quoted(folder / "bdpt.png"),
                                 folder)
                .exit_code,
            0);
  const std::string rendered = test::read_text_file(folder / "bdpt.png");
  EXPECT_EQ(test::read_text_file(folder / "bdpt" / "q32.32.png"), rendered);
  EXPECT_NE(test::read_text_file(folder / "path" / "q32.32.png"), rendered);
}

// What bdpt cannot do is refused with one line: bands over several devices (splats cross them), adaptive sampling
// (a stopped pixel would still take splats), paths longer than its vertex store.
TEST(Bidirectional, RefusesWhatItCannotDo) {
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  RenderSettings settings = scene.render;
  settings.width = 16;
  settings.height = 8;
  const FlatScene<float> flat = flatten_scene<float>(scene, settings);
  const std::unique_ptr<RenderBackend<float>> backend = make_cpu_backend<float>(1, Integrator::kBidirectional);
  backend->upload(flat);
  std::vector<FilmPixel> band(16 * 4);
  EXPECT_THROW(backend->render_rows(0, 4, 0, 1, band), BackendError);
  EXPECT_THROW(backend->stop_clean_pixels(16, 8, 4, 0.01), BackendError);
  RenderSettings deep = settings;
  deep.max_depth = kMaxBidirectionalDepth + 1;
  EXPECT_THROW(backend->upload(flatten_scene<float>(scene, deep)), BackendError);

  test::TempDir folder;
  const test::CommandResult result = test::run_pathtracer(
      "render " + test::quoted(test::scene_path("tiny.json")) + " --quiet --integrator bdpt --noise-threshold 0.01 --spp 4 --width 16 --height 8 -o " +
          test::quoted(folder / "out.pfm"),
      folder);
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("adaptive sampling"), std::string::npos) << result.err;
  EXPECT_EQ(test::lines_of(result.err).size(), 1u) << result.err;
  EXPECT_FALSE(std::filesystem::exists(folder / "out.pfm"));
}

// Vertex merging refuses what bdpt refuses, and fixed point (a disc's area times the number of light subpaths, squared,
// has no room in it), each with one line.
TEST(VertexMerging, RefusesWhatItCannotDo) {
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  RenderSettings settings = scene.render;
  settings.width = 16;
  settings.height = 8;
  const std::unique_ptr<RenderBackend<float>> backend = make_cpu_backend<float>(1, Integrator::kVertexMerging);
  backend->upload(flatten_scene<float>(scene, settings));
  std::vector<FilmPixel> band(16 * 4);
  EXPECT_THROW(backend->render_rows(0, 4, 0, 1, band), BackendError);
  EXPECT_THROW(backend->stop_clean_pixels(16, 8, 4, 0.01), BackendError);

  test::TempDir folder;
  const test::CommandResult result = test::run_pathtracer("render " + test::quoted(test::scene_path("tiny.json")) +
                                                              " --quiet --integrator vcm --number-format q32.32 --spp 2 --width 16 --height 8 -o " +
                                                              test::quoted(folder / "out.pfm"),
                                                          folder);
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("fixed point"), std::string::npos) << result.err;
  EXPECT_EQ(test::lines_of(result.err).size(), 1u) << result.err;
  EXPECT_FALSE(std::filesystem::exists(folder / "out.pfm"));
}

}  // namespace
}  // namespace pt
