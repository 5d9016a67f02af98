// The SYCL backend beyond the shared parity test (tests/test_backend_parity.cpp, float): parity in double, the
// image independent of how samples are split, device selection, listing and errors. Skipped without SYCL.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "backends/cpu/cpu_backend.hpp"
#include "backends/registry.hpp"
#include "film/film.hpp"
#include "integrators/wavefront.hpp"
#include "loading/scene_loader.hpp"
#include "test_support.hpp"
#if PT_HAVE_SYCL
#include "backends/sycl/sycl_backend.hpp"
#endif

#ifndef PT_SOURCE_DIR
#error "PT_SOURCE_DIR must name the source tree"
#endif

namespace pt {
namespace {

#if PT_HAVE_SYCL

// The device the tests use: test::sycl_test_device().
int test_device() { return test::sycl_test_device(); }

struct Rendered {
  LinearImage image;
  RenderStats stats;
};

template <class T>
Rendered render_on(RenderBackend<T>& backend, const std::string& scene_name, u32 width, u32 height, u32 spp, u32 seed) {
  const SceneDescription scene = load_scene_file(test::scene_path(scene_name));
  RenderSettings settings = scene.render;
  settings.width = width;
  settings.height = height;
  settings.samples_per_pixel = spp;
  settings.seed = seed;
  const RenderResult result = render_scene(backend, flatten_scene<T>(scene, settings));
  return Rendered{result.image, result.stats};
}

double rmse(const LinearImage& a, const LinearImage& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = static_cast<double>(a.rgb[i]) - b.rgb[i];
    sum += d * d;
  }
  return std::sqrt(sum / static_cast<double>(a.rgb.size()));
}

double mean(const LinearImage& image) {
  double sum = 0;
  for (const float v : image.rgb) sum += v;
  return sum / static_cast<double>(image.rgb.size());
}

double fraction_close(const LinearImage& a, const LinearImage& b, double relative) {
  std::size_t close = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double x = a.rgb[i], y = b.rgb[i];
    if (std::abs(x - y) <= relative * std::max(1.0, std::abs(x))) ++close;
  }
  return static_cast<double>(close) / static_cast<double>(a.rgb.size());
}

// Same seed on both backends, with the bound of tests/test_backend_parity.cpp: the images differ only where the
// compilers round differently and a path takes another branch, so their distance must be far below the noise
// between two seeds of the CPU image.
template <class T>
void expect_parity(const std::string& scene, u32 width, u32 height, u32 spp) {
  const std::unique_ptr<RenderBackend<T>> cpu = make_cpu_backend<T>(0, Integrator::kMegakernel);
  const std::unique_ptr<RenderBackend<T>> sycl = make_sycl_backend<T>(test_device());
  const Rendered reference = render_on(*cpu, scene, width, height, spp, 7);
  const Rendered other_seed = render_on(*cpu, scene, width, height, spp, 8);
  const Rendered tested = render_on(*sycl, scene, width, height, spp, 7);
  ASSERT_EQ(tested.image.rgb.size(), reference.image.rgb.size());

  const double noise = rmse(reference.image, other_seed.image);
  const double distance = rmse(reference.image, tested.image);
  const double mean_cpu = mean(reference.image), mean_sycl = mean(tested.image);
  const double close = fraction_close(reference.image, tested.image, 1e-3);
  std::printf(
      "%s %ux%u %u spp (%s) on %s: rmse %.3g (seed-to-seed noise %.3g, ratio %.3g), means %.6g / %.6g, "
      "%.2f%% of channels within 1e-3, dropped %llu / %llu\n",
      scene.c_str(), width, height, spp, sizeof(T) == 4 ? "float" : "double", sycl->name().c_str(), distance, noise,
      noise > 0 ? distance / noise : 0.0, mean_cpu, mean_sycl, 100 * close, static_cast<unsigned long long>(tested.stats.dropped_samples),
      static_cast<unsigned long long>(reference.stats.dropped_samples));

  EXPECT_GT(noise, 0.0) << "two seeds gave the same image: the bound below would mean nothing";
  EXPECT_LE(distance, 0.25 * noise);
  EXPECT_NEAR(mean_sycl, mean_cpu, 0.005 * std::abs(mean_cpu));
  EXPECT_GE(close, 0.90);
  // Every sample is traced on both, so the work counted must agree as closely as the images do.
  EXPECT_EQ(tested.stats.samples, reference.stats.samples);
  EXPECT_NEAR(static_cast<double>(tested.stats.rays), static_cast<double>(reference.stats.rays), 0.005 * reference.stats.rays);
}

// The double kernels are a separate instantiation, which the shared parity test (float) does not cover.
TEST(SyclBackend, TinySceneMatchesCpuDouble) { expect_parity<double>("tiny.json", 64, 48, 16); }

// Both integrators: the megakernel's launches and the wavefront's batches must not depend on the calls' split.
class SyclSampleSplit : public ::testing::TestWithParam<Integrator> {};

TEST_P(SyclSampleSplit, ImageDoesNotDependOnHowSamplesAreSplit) {
  const std::unique_ptr<RenderBackend<float>> sycl = make_sycl_backend<float>(test_device(), GetParam());
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  const FlatScene<float> flat = flatten_scene<float>(scene, scene.render);
  std::vector<FilmPixel> whole, split;
  sycl->upload(flat);
  sycl->render(0, 6);
  sycl->read_film(whole);
  sycl->upload(flat);
  sycl->render(0, 1);
  sycl->render(1, 2);
  sycl->render(3, 3);
  sycl->read_film(split);
  ASSERT_EQ(whole.size(), split.size());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    ASSERT_EQ(whole[i].r, split[i].r) << "pixel " << i;
    ASSERT_EQ(whole[i].g, split[i].g) << "pixel " << i;
    ASSERT_EQ(whole[i].b, split[i].b) << "pixel " << i;
    ASSERT_EQ(whole[i].samples, split[i].samples) << "pixel " << i;
    ASSERT_EQ(whole[i].rays, split[i].rays) << "pixel " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Integrators, SyclSampleSplit, ::testing::Values(Integrator::kMegakernel, Integrator::kWavefront),
                         [](const ::testing::TestParamInfo<Integrator>& info) {
                           return std::string(info.param == Integrator::kWavefront ? "Wavefront" : "Megakernel");
                         });

// The wavefront stages report a time for each stage they ran.
TEST(SyclBackend, WavefrontReportsStageTimes) {
  const std::unique_ptr<RenderBackend<float>> sycl = make_sycl_backend<float>(test_device(), Integrator::kWavefront);
  const SceneDescription scene = load_scene_file(test::scene_path("tiny.json"));
  sycl->upload(flatten_scene<float>(scene, scene.render));
  sycl->render(0, 2);
  const auto stages = sycl->stage_seconds();
  ASSERT_EQ(stages.size(), kWavefrontStageNames.size());
  for (const auto& [name, seconds] : stages) EXPECT_GT(seconds, 0.0) << name;
}

TEST(SyclBackend, MissingDeviceIsOneLineError) {
  try {
    make_sycl_backend<float>(1000);
    FAIL() << "device 1000 was accepted";
  } catch (const BackendError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("sycl: ", 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(SyclBackend, SelectedByName) {
  const std::unique_ptr<RenderBackend<float>> backend = make_backend<float>("sycl", 0, 0, Integrator::kMegakernel, test_device());
  EXPECT_EQ(backend->name().rfind("sycl", 0), 0u) << backend->name();
  const std::vector<std::string> names = backend_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "sycl"), names.end());
  const std::unique_ptr<RenderBackend<float>> wavefront = make_backend<float>("sycl", 0, 0, Integrator::kWavefront, test_device());
  EXPECT_NE(wavefront->name().find("wavefront"), std::string::npos) << wavefront->name();
}

TEST(SyclBackend, AutoTakesTheMegakernelOnEveryDevice) {
  const std::unique_ptr<RenderBackend<float>> backend = make_backend<float>("sycl", 0, 0, Integrator::kAuto, test_device());
  EXPECT_NE(backend->name().find("megakernel"), std::string::npos) << backend->name();
}

#ifdef PT_PATHTRACER_BINARY
// --sycl-device picks the device of a render or a bench, the default --device list (0) notwithstanding: a device that
// does not exist is refused, and each listed device renders under its own name.
TEST(SyclBackend, SyclDeviceOptionPicksTheDevice) {
  test::TempDir folder;
  const test::CommandResult missing = test::run_pathtracer(
      "bench " + test::quoted(test::scene_path("tiny.json")) + " --backend sycl --sycl-device 1000 --width 8 --height 8 --spp 1 --runs 1", folder);
  EXPECT_NE(missing.exit_code, 0) << missing.err;
  EXPECT_NE(missing.err.find("1000"), std::string::npos) << missing.err;
  const std::vector<DeviceDescription> devices = sycl_devices();
  for (std::size_t index = 0; index < devices.size(); ++index) {
    if (devices[index].index < 0) continue;  // no usable device: the line above already failed
    const std::unique_ptr<RenderBackend<float>> backend =
        make_render_backend<float>("sycl", parse_device_list("0", "sycl"), 0, Integrator::kMegakernel, static_cast<int>(index));
    EXPECT_NE(backend->name().find(devices[index].name), std::string::npos) << index << ": " << backend->name();
  }
}

TEST(SyclBackend, DevicesCommandListsSyclDevices) {
  FILE* pipe = popen(("'" + test::pathtracer_binary() + "' devices").c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) output += buffer;
  EXPECT_EQ(pclose(pipe), 0);
  EXPECT_NE(output.find("\nsycl 0: "), std::string::npos) << output;
}
#endif

#else

TEST(SyclBackend, NotBuilt) { GTEST_SKIP() << "built without the SYCL backend (configure with -DPT_SYCL=ON)"; }

#endif

}  // namespace
}  // namespace pt
