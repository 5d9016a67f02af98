// Renders in fixed-point formats against float: a wide format must match within a stated PSNR, a scene that
// does not fit a narrow format must be refused with one clear error, and saturations reach the render statistics.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "backends/registry.hpp"
#include "base/number_formats.hpp"
#include "film/film.hpp"
#include "loading/scene_loader.hpp"

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

// Q16.16 keeps products exact in its intersection tests and squares no distance, so it renders the tiny scene
// (a ground of radius 100) at its own scale; it scaled it by 1/4 before, to keep squared distances in range.
TEST(FixedPointRender, Q16_16RendersTheTinySceneUnscaled) {
  RenderSettings settings;
  const SceneDescription scene = tiny_scene(settings);
  const FlatScene<Fixed<16, 16>> flat = flatten_scene<Fixed<16, 16>>(scene, settings);
  EXPECT_EQ(flat.scale, 1.0);
  EXPECT_GE(psnr(render<Fixed<16, 16>>(scene, settings).image, render<float>(scene, settings).image), 28.0);
}

// A sphere of radius 10000 beside the tiny scene: Q10.10 needs coordinates within 64, so the scene is scaled by
// 1/512, and the ground checker's 3.18 cells per unit become 1630, beyond Q10.10's 511. (A 0.01-unit quad no
// longer does this: a quad stores its dual edges times a power of two near its edge length, sizes near 1.)
TEST(FixedPointRender, SceneThatDoesNotFitIsRefused) {
  RenderSettings settings;
  SceneDescription scene = tiny_scene(settings);
  scene.objects.push_back(SceneObject{Sphere<double>{{0, -10000, 0}, 10000}, {}, 0});
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

// Rendering the tiny scene in Q12.12 counts saturation events (about one per two samples; Q32.32 counts as many
// there, with an image within 129 dB of double's, so they are values beyond any range, not a lack of precision).
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

// Bidirectional path tracing renders in fixed point with its weights and its light subpaths' throughput formed in a
// unit of length in which the scene measures about one (kernel/bidirectional.hpp, "The weights' unit of length"). In
// the scene's own unit the Cornell box's light area, squared, lies beyond Q32.32's range (7.7 dB against double,
// measured), and the camera's image area was a square beyond it too (28 dB); a unit set by the scene's extent left
// seed-default's segments a few steps in the fourth power (37 dB). With the unit set by the camera's distance
// (docs/numerics.md, 64x48, 16 spp): Q32.32 92 dB on the Cornell box, 134 dB on the caustics scene, 82 dB on
// seed-default; Q16.16 36 dB on the Cornell box, counting its saturations.
TEST(FixedPointRender, BidirectionalFollowsDoubleInQ32_32) {
  for (const char* name : {"cornell-box", "caustics", "seed-default"}) {
    const SceneDescription scene = load_scene_file(std::string(PT_SOURCE_DIR "/scenes/") + name + ".json");
    RenderSettings settings = scene.render;
    settings.width = 48;
    settings.height = 36;
    settings.samples_per_pixel = 8;
    settings.max_depth = 8;
    const RenderResult reference = render<double>(scene, settings, Integrator::kBidirectional);
    EXPECT_GE(psnr(render<Fixed<32, 32>>(scene, settings, Integrator::kBidirectional).image, reference.image), 70.0) << name;
    if (std::string(name) == "cornell-box") {
      const RenderResult narrow = render<Fixed<16, 16>>(scene, settings, Integrator::kBidirectional);
      EXPECT_GE(psnr(narrow.image, reference.image), 30.0) << name;
      EXPECT_GT(narrow.stats.saturations, 0u);
    }
  }
}

}  // namespace
}  // namespace pt
