// Renders in fixed-point formats against float: a wide format must match within a stated PSNR, a scene that
// does not fit a narrow format must be refused with one clear error, and saturations reach the render statistics.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "app/backends.hpp"
#include "film/film.hpp"
#include "base/number_formats.hpp"
#include "scene/scene_loader.hpp"

namespace pt {
namespace {

SceneDescription tiny_scene(RenderSettings& settings) {
  SceneDescription scene = load_scene_file(PT_SOURCE_DIR "/scenes/tiny.json");
  settings = scene.render;
  settings.width = 64;
  settings.height = 48;
  settings.samples_per_pixel = 8;
  return scene;
}

template <class T>
RenderResult render(const SceneDescription& scene, const RenderSettings& settings, Integrator integrator = Integrator::kMegakernel) {
  auto backend = make_backend<T>("cpu", 2, 0, integrator);
  return render_scene(*backend, flatten_scene<T>(scene, settings));
}

// PSNR of the 8-bit display values (clamped, sRGB), as `pathtracer numerics` measures it.
double psnr(const LinearImage& a, const LinearImage& b) {
  double squared = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double x = linear_to_srgb(std::clamp(a.rgb[i], 0.0f, 1.0f)), y = linear_to_srgb(std::clamp(b.rgb[i], 0.0f, 1.0f));
    squared += (x - y) * (x - y);
  }
  const double rmse = std::sqrt(squared / a.rgb.size());
  return rmse > 0 ? 20 * std::log10(1 / rmse) : 200;
}

// Q32.32 follows float's paths almost everywhere: measured 67 dB; 50 dB leaves room for compilers and libm.
TEST(FixedPointRender, WideFormatMatchesFloatWithin50Db) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  const RenderResult reference = render<float>(scene, settings);
  const RenderResult wide = render<Fixed<32, 32>>(scene, settings);
  EXPECT_GE(psnr(wide.image, reference.image), 50.0);
}

// Q16.16 must render the tiny scene recognisably (measured about 29 dB at 16 spp) after scaling it by 1/4.
TEST(FixedPointRender, Q16_16RendersTheScaledScene) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  const FlatScene<Fixed<16, 16>> flat = flatten_scene<Fixed<16, 16>>(scene, settings);
  EXPECT_EQ(flat.scale, 0.25);
  EXPECT_GE(psnr(render<Fixed<16, 16>>(scene, settings).image, render<float>(scene, settings).image), 20.0);
}

// A 0.01-unit quad beside a 1000-unit sphere: fitting the sphere's squared distances into Q10.10 scales the scene
// by 1/256, which makes the quad's dual edges (1 / its edge length) about 25600, far beyond Q10.10's 511.
TEST(FixedPointRender, SceneThatDoesNotFitIsRefused) {
  RenderSettings settings;
  SceneDescription scene = tiny_scene(settings);
  scene.objects.push_back(SceneObject{Sphere<double>{{0, -1000, 0}, 1000}, {}, 0});
  scene.objects.push_back(SceneObject{QuadSettings{{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}}, {}, 0});
  try {
    flatten_scene<Fixed<10, 10>>(scene, settings);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("tiny.json"), std::string::npos) << message;
    EXPECT_NE(message.find("does not fit q10.10"), std::string::npos) << message;
  }
  using Q10_10 = Fixed<10, 10>;
  EXPECT_NO_THROW(flatten_scene<Q10_10>(tiny_scene(settings), settings));
}

// Scaled by 1/16 for Q12.12, the tiny scene's triangle has edges of about 0.05: their cross product's squared
// length falls below one step, so normalising the geometric normal divides by zero. Those events are counted.
TEST(FixedPointRender, SaturationsReachTheStatistics) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  using Q12_12 = Fixed<12, 12>;
  EXPECT_GT(render<Q12_12>(scene, settings).stats.saturations, 0u);
  EXPECT_EQ(render<float>(scene, settings).stats.saturations, 0u);
}

// The wavefront runs the same arithmetic on the same samples as the megakernel, so it counts the same saturations
// (the device layer counts them for every launch of either integrator); a second render on the same backend counts
// its own only.
TEST(FixedPointRender, SaturationsAreTheSameForBothIntegratorsAndCountedPerRender) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  using Q12_12 = Fixed<12, 12>;
  const u64 megakernel = render<Q12_12>(scene, settings, Integrator::kMegakernel).stats.saturations;
  EXPECT_GT(megakernel, 0u);
  EXPECT_EQ(render<Q12_12>(scene, settings, Integrator::kWavefront).stats.saturations, megakernel);
  auto backend = make_backend<Q12_12>("cpu", 2, 0);
  const FlatScene<Q12_12> flat = flatten_scene<Q12_12>(scene, settings);
  EXPECT_EQ(render_scene(*backend, flat).stats.saturations, megakernel);
  EXPECT_EQ(render_scene(*backend, flat).stats.saturations, megakernel);
}

}  // namespace
}  // namespace pt
