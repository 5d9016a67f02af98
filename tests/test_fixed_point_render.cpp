// Renders in fixed-point formats against float: a wide format must match within a stated PSNR, a scene that
// does not fit a narrow format must be refused with one clear error, and saturations reach the render statistics.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "app/backends.hpp"
#include "film/film.hpp"
#include "flat/number_formats.hpp"
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
RenderResult render(const SceneDescription& scene, const RenderSettings& settings) {
  auto backend = make_backend<T>("cpu", 2, 0);
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

// The tiny scene's quads need w = 1 / area far beyond Q10.10's range once the scene is scaled to fit.
TEST(FixedPointRender, SceneThatDoesNotFitIsRefused) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  try {
    flatten_scene<Fixed<10, 10>>(scene, settings);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("tiny.json"), std::string::npos) << message;
    EXPECT_NE(message.find("does not fit q10.10"), std::string::npos) << message;
  }
}

// Q24.8's reciprocals of near-axis ray directions overflow in the BVH slab test: those events are counted.
TEST(FixedPointRender, SaturationsReachTheStatistics) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  using Q24_8 = Fixed<24, 8>;
  EXPECT_GT(render<Q24_8>(scene, settings).stats.saturations, 0u);
  EXPECT_EQ(render<float>(scene, settings).stats.saturations, 0u);
}

}  // namespace
}  // namespace pt
