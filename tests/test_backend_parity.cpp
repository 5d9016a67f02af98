// Backend parity: every shipped scene, rendered with the same seed and settings on the CPU and on each other
// backend that is built (CUDA, SYCL), gives the same image within a stated bound. Skips, saying why, where a
// backend is not built or has no device.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "backends/registry.hpp"
#include "film/film.hpp"
#include "loading/scene_loader.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt {
namespace {

// Why not bitwise: the GPU evaluates sin, cos, atan2, asin and log with other (equally accurate) algorithms than
// glibc, and nvcc contracts a*b+c into fused multiply-adds (unless built with -DPT_CUDA_FMAD=OFF). Either changes the last bits of some values; where such a
// difference flips a discrete decision (a grazing hit, the Fresnel choice, a Russian-roulette draw near q) that
// sample follows another path and becomes an independent sample. So the bound is statistical:
//  - same-seed images must be much closer than two CPU images of different seeds (RMSE at most a quarter), which
//    holds only if nearly all samples are shared;
//  - the image means agree to 0.5% (diverged samples are unbiased, so they only add noise);
//  - at least 90% of pixel channels agree to 1e-3 relative (the share of pixels touched by a diverged sample).
// With -DPT_CUDA_FMAD=OFF the differences shrink to the transcendental functions alone. A SYCL implementation
// may differ from the CPU build for the same reasons (AdaptiveCpp's omp target matches it bit for bit; its
// generic target JIT-compiles for the host CPU with fused multiply-adds), so the same bound applies.
LinearImage render_with(const std::string& backend, const SceneDescription& scene, const RenderSettings& settings) {
  const FlatScene<float> flat = flatten_scene<float>(scene, settings);
  auto renderer = make_backend<float>(backend, 0, 0);
  return render_scene(*renderer, flat).image;
}

// Renders the scene on the CPU at two seeds and on `backend` at the first, and checks the bound above.
// A shipped scene by name, or one of the real models (Debian's assimp-testmodels) named in real_model_path.
std::filesystem::path real_model_path(const std::string& name) {
  const std::filesystem::path root = "/usr/share/assimp/models";
  if (name == "engine_glb") return root / "glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
  if (name == "box_textured_gltf") return root / "glTF2/BoxTextured-glTF/BoxTextured.gltf";
  if (name == "spider_obj") return root / "OBJ/spider.obj";
  if (name == "wuson_ply") return root / "PLY/Wuson.ply";
  return {};
}

void expect_parity_with_cpu(const std::string& backend, const std::string& scene_name) {
  const std::filesystem::path model = real_model_path(scene_name);
  const SceneDescription scene = load_scene_file(model.empty() ? test::scene_path(scene_name + ".json") : model);
  RenderSettings settings = scene.render;
  settings.width = 96;
  settings.height = 72;
  settings.samples_per_pixel = 64;
  settings.seed = 11;
  const LinearImage cpu = render_with("cpu", scene, settings);
  const LinearImage gpu = render_with(backend, scene, settings);
  RenderSettings other_seed = settings;
  other_seed.seed = 12;
  const LinearImage cpu_other = render_with("cpu", scene, other_seed);

  test::expect_same_samples_as_the_cpu(cpu, gpu, cpu_other, scene_name + " (" + backend + ")");
}

class BackendParity : public ::testing::TestWithParam<std::string> {};

TEST_P(BackendParity, GpuImageMatchesCpuImageForTheSameSeed) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  const std::filesystem::path model = real_model_path(GetParam());
  if (!model.empty() && !std::filesystem::exists(model)) GTEST_SKIP() << model << " is not installed (assimp-testmodels)";
  expect_parity_with_cpu("cuda", GetParam());
#endif
}

TEST_P(BackendParity, SyclImageMatchesCpuImageForTheSameSeed) {
#if !PT_HAVE_SYCL
  GTEST_SKIP() << "the SYCL backend is not built (configure with -DPT_SYCL=ON)";
#else
  const std::filesystem::path model = real_model_path(GetParam());
  if (!model.empty() && !std::filesystem::exists(model)) GTEST_SKIP() << model << " is not installed (assimp-testmodels)";
  expect_parity_with_cpu("sycl", GetParam());
#endif
}

INSTANTIATE_TEST_SUITE_P(ShippedScenes, BackendParity,
                         ::testing::Values("tiny", "meshes", "seed-default", "book1-final", "book2-final", "cornell-box", "cornell-smoke",
                                           "environment", "normal-maps"),
                         test::scene_test_name);
INSTANTIATE_TEST_SUITE_P(RealModels, BackendParity, ::testing::Values("engine_glb", "box_textured_gltf", "spider_obj", "wuson_ply"),
                         test::scene_test_name);

}  // namespace
}  // namespace pt
