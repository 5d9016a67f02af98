// The rtl backend: the wavefront integrator with its intersect stage in the traversal engine's cycle-accurate model
// renders the CPU wavefront's fixed-point image bit for bit, and refuses what its engine does not do with one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>

#include "backends/registry.hpp"
#include "film/film.hpp"
#include "kernel/fixed_point.hpp"
#include "loading/scene_loader.hpp"
#include "test_support.hpp"
#if PT_HAVE_RTL
#include "backends/rtl/rtl_backend.hpp"
#endif

namespace pt {
namespace {

#if PT_HAVE_RTL
using Q16 = Fixed<16, 16>;

RenderSettings tiny_settings(const SceneDescription& scene) {
  RenderSettings settings = scene.render;
  settings.width = 24;
  settings.height = 16;
  settings.samples_per_pixel = 2;
  settings.seed = 3;
  return settings;
}

class RtlBackend : public ::testing::TestWithParam<std::string> {};

TEST_P(RtlBackend, RendersTheCpuWavefrontImageBitForBit) {
  const SceneDescription description = load_scene_file(test::scene_path(GetParam() + ".json"));
  const FlatScene<Q16> flat = flatten_scene<Q16>(description, tiny_settings(description));
  const RenderResult cpu = test::render(flat, 2, Integrator::kWavefront);
  const RenderResult rtl = render_scene(*make_backend<Q16>("rtl", 2, 0, Integrator::kWavefront), flat);
  ASSERT_EQ(cpu.image.rgb.size(), rtl.image.rgb.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < cpu.image.rgb.size(); ++i) differ += std::memcmp(&cpu.image.rgb[i], &rtl.image.rgb[i], sizeof(float)) != 0;
  EXPECT_EQ(differ, 0u) << "of " << cpu.image.rgb.size() << " values";
  EXPECT_EQ(cpu.stats.rays, rtl.stats.rays);
}

INSTANTIATE_TEST_SUITE_P(ShippedScenes, RtlBackend,
                         ::testing::Values("cornell-box", "cornell-smoke", "book1-final", "book2-final", "environment", "meshes", "normal-maps",
                                           "seed-default", "tiny"));

std::string refusal(const std::function<void()>& attempt) {
  try {
    attempt();
  } catch (const BackendError& e) {
    return e.what();
  }
  return "";
}

TEST(RtlBackendRefuses, FloatingPointFormatsTheMegakernelAndScenesItCannotHold) {
  EXPECT_NE(refusal([] { make_backend<float>("rtl", 1, 0, Integrator::kWavefront); }).find("fixed point"), std::string::npos);
  EXPECT_NE(refusal([] { make_backend<Q16>("rtl", 1, 0, Integrator::kMegakernel); }).find("wavefront integrator only"), std::string::npos);
  // More spheres than the engine's primitive memory holds (65,536).
  SceneDescription crowd = test::generated_scene({0, 0, 60});
  crowd.textures.push_back(SolidTexture<double>{{0.5, 0.5, 0.5}});
  crowd.materials.push_back(Lambertian<double>{0});
  for (int i = 0; i < 70000; ++i) {
    SceneObject sphere;
    sphere.shape = Sphere<double>{{(i % 280) * 0.1 - 14.0, (i / 280) * 0.1 - 12.5, 0.0}, 0.04};
    crowd.objects.push_back(sphere);
  }
  const FlatScene<Q16> flat = flatten_scene<Q16>(crowd, tiny_settings(crowd));
  auto renderer = make_backend<Q16>("rtl", 1, 0, Integrator::kAuto);
  EXPECT_NE(refusal([&] { renderer->upload(flat); }).find("the traversal engine holds 65536"), std::string::npos);
}

std::string run_command(const std::string& command, int& exit_code) {
  FILE* pipe = popen(command.c_str(), "r");
  std::string output;
  if (!pipe) return output;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) output += buffer;
  exit_code = WEXITSTATUS(pclose(pipe));
  return output;
}

// From the command line too, where the CPU backend is named and keeps only the tree it walks.
TEST(RtlBackendCommand, WritesTheCpuWavefrontsFileAndSaysWhatTheEngineDid) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "pt-rtl-command";
  std::filesystem::create_directories(dir);
  const std::string render = test::pathtracer_binary() + " render " + test::scene_path("cornell-box.json").string() +
                             " --number-format q16.16 --width 16 --height 12 --spp 2 --integrator wavefront";
  int cpu_exit = -1, rtl_exit = -1;
  run_command(render + " --backend cpu -o " + (dir / "cpu.pfm").string() + " 2>&1", cpu_exit);
  const std::string said = run_command(render + " --backend rtl -o " + (dir / "rtl.pfm").string() + " 2>&1", rtl_exit);
  ASSERT_EQ(cpu_exit, 0);
  ASSERT_EQ(rtl_exit, 0) << said;
  EXPECT_EQ(test::read_text_file(dir / "cpu.pfm"), test::read_text_file(dir / "rtl.pfm"));
  EXPECT_NE(said.find("traversal engine:"), std::string::npos) << said;
  EXPECT_NE(said.find("shadow rays:"), std::string::npos) << said;
  std::filesystem::remove_all(dir);
}

TEST(RtlBackendRefuses, SeveralDevicesRatherThanRenderingOnTheCpu) {
  EXPECT_THROW(parse_device_list("all", "rtl"), InputError);
  EXPECT_THROW(parse_device_list("0,cpu", "rtl"), InputError);
  EXPECT_EQ(parse_device_list("0", "rtl").entries.size(), 1u);
}

TEST(RtlBackendRefuses, AFloatRenderWithOneLineAndExitCodeOne) {
  const std::string command = test::pathtracer_binary() + " render " + test::scene_path("cornell-box.json").string() +
                              " --backend rtl --width 8 --height 8 --spp 1 -o /tmp/pt-rtl-refused.png 2>&1";
  int status = -1;
  const std::string output = run_command(command, status);
  EXPECT_EQ(status, 1) << output;
  EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
  EXPECT_NE(output.find("fixed point"), std::string::npos) << output;
}
#endif

}  // namespace
}  // namespace pt
