// Adaptive sampling: clean pixels stop taking samples, the image stays deterministic and resumable, and its expected
// value does not move.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "backends/registry.hpp"
#include "film/adaptive.hpp"
#include "film/film.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt::adaptive_sampling_test {

FlatScene<float> tiny_adaptive_scene(u32 samples, double threshold, u32 seed = 3) {
  FlatScene<float> scene = test::tiny_reference_scene<float>(samples, seed);
  scene.noise_threshold = threshold;
  return scene;
}

std::vector<FilmPixel> film_of(const RenderedFilm& film) { return {film.pixels().begin(), film.pixels().end()}; }

TEST(AdaptiveSampling, JudgementsFallAtFixedSampleCounts) {
  EXPECT_EQ(next_judgement(0), 16u);
  EXPECT_EQ(next_judgement(15), 16u);
  EXPECT_EQ(next_judgement(16), 20u);
  EXPECT_EQ(next_judgement(30), 32u);
  EXPECT_EQ(next_judgement(32), 40u);
  EXPECT_EQ(next_judgement(63), 64u);
  EXPECT_EQ(next_judgement(64), 80u);
  EXPECT_EQ(next_judgement(1000), 1024u);
  for (u32 n : {16u, 20u, 28u, 40u, 56u, 80u, 112u, 128u, 1536u}) EXPECT_TRUE(is_judgement(n)) << n;
  for (u32 n : {0u, 8u, 12u, 18u, 30u, 36u, 60u, 72u, 1000u}) EXPECT_FALSE(is_judgement(n)) << n;
  EXPECT_EQ(next_judgement(0xfffffff0u), 0xffffffffu);  // no overflow near the largest count
}

// Pixels with no noise (the sky) stop at the first judgement; noisy ones (near the light, behind the glass) go on
// to the end; every pixel took exactly the samples up to its stop, and the statistics count those, not more.
TEST(AdaptiveSampling, CleanPixelsStopAndNoisyOnesGoOn) {
  const FlatScene<float> scene = tiny_adaptive_scene(96, 0.02);
  const auto backend = make_cpu_backend<float>(2, Integrator::kMegakernel);
  const RenderedFilm film = render_film(*backend, scene);
  EXPECT_EQ(film.samples_done, 96u);
  std::size_t at_first = 0, to_the_end = 0;
  u64 given = 0;
  for (const FilmPixel& p : film.pixels()) {
    const u32 expected = p.stopped_at != 0 ? p.stopped_at : 96u;
    if (p.stopped_at != 0) {
      EXPECT_TRUE(is_judgement(p.stopped_at)) << p.stopped_at;
    }
    EXPECT_EQ(p.samples, expected);  // the scene has no non-finite samples
    given += expected;
    at_first += p.stopped_at == kAdaptiveFirstJudgement;
    to_the_end += p.stopped_at == 0;
  }
  const std::size_t pixels = film.pixels().size();
  EXPECT_GT(at_first, pixels / 10) << "the sky is clean after 16 samples";
  EXPECT_GT(to_the_end, pixels / 20) << "noisy pixels take every sample";
  EXPECT_LT(to_the_end, pixels);
  EXPECT_EQ(film.stats.samples, given);
  EXPECT_EQ(film.stats.dropped_samples, 0u);
  std::printf("%zu of %zu pixels stopped at 16 samples, %zu took all 96; %.2f of the samples of a uniform render\n", at_first, pixels,
              to_the_end, static_cast<double>(given) / (96.0 * pixels));
}

// A lower threshold asks for more samples: the judgement measures error, not a fixed fraction.
TEST(AdaptiveSampling, LowerThresholdTakesMoreSamples) {
  const auto samples_taken = [](double threshold) {
    const auto backend = make_cpu_backend<float>(2, Integrator::kMegakernel);
    return render_film(*backend, tiny_adaptive_scene(64, threshold)).stats.samples;
  };
  const u64 loose = samples_taken(0.1), tight = samples_taken(0.01), all = 64ull * 64 * 48;
  EXPECT_LT(loose, tight);
  EXPECT_LE(tight, all);
  EXPECT_EQ(samples_taken(0), all);
}

// The same film bit for bit whatever the threads and the integrator: judgements fall at fixed sample counts and
// read only the film (and the passes: the resumed renders below).
TEST(AdaptiveSampling, SameFilmWhateverTheThreadsAndIntegrator) {
  const FlatScene<float> scene = tiny_adaptive_scene(48, 0.03);
  const auto one = make_cpu_backend<float>(1, Integrator::kMegakernel);
  const auto three = make_cpu_backend<float>(3, Integrator::kWavefront);
  const std::vector<FilmPixel> reference = film_of(render_film(*one, scene));
  EXPECT_TRUE(test::same_film(reference, film_of(render_film(*three, scene))));
  std::size_t stopped = 0;
  for (const FilmPixel& p : reference) stopped += p.stopped_at != 0;
  EXPECT_GT(stopped, 0u);
}

// Stopped after its second pass, saved, and resumed by a new backend, an adaptive render ends with the film of an
// uninterrupted one: the stops travel with the film.
void expect_adaptive_resume_is_bitwise_equal(Integrator integrator) {
  const FlatScene<float> scene = tiny_adaptive_scene(48, 0.03);
  const std::vector<FilmPixel> whole = film_of(render_film(*make_cpu_backend<float>(2, integrator), scene));
  for (int stop_after : {1, 2, 3}) {
    std::vector<FilmPixel> saved;
    u32 saved_samples = 0;
    int passes = 0;
    RenderControl stop;
    stop.stop_requested = [&] { return passes++ >= stop_after; };
    stop.checkpoint = [&](std::span<const FilmPixel> pixels, u32 samples) {
      saved.assign(pixels.begin(), pixels.end());
      saved_samples = samples;
    };
    const auto first_backend = make_cpu_backend<float>(2, integrator), second_backend = make_cpu_backend<float>(1, integrator);
    const RenderedFilm part = render_film(*first_backend, scene, {}, stop);
    ASSERT_LT(part.samples_done, 48u);
    RenderControl resume;
    resume.start_film = saved;
    resume.start_samples = saved_samples;
    const RenderedFilm rest = render_film(*second_backend, scene, {}, resume);
    EXPECT_EQ(rest.samples_done, 48u);
    EXPECT_TRUE(test::same_film(film_of(rest), whole)) << "stopped after " << stop_after << " passes, at " << saved_samples << " samples";
  }
}
TEST(AdaptiveSampling, ResumedMegakernelRenderIsBitwiseEqual) { expect_adaptive_resume_is_bitwise_equal(Integrator::kMegakernel); }
TEST(AdaptiveSampling, ResumedWavefrontRenderIsBitwiseEqual) { expect_adaptive_resume_is_bitwise_equal(Integrator::kWavefront); }

// Where every pixel is clean, the render ends at that judgement and counts as complete.
TEST(AdaptiveSampling, RenderEndsWhenEveryPixelIsClean) {
  const SceneDescription sky = test::parse(R"({
    "render": {"width": 16, "height": 8, "samples_per_pixel": 1000, "max_depth": 4},
    "camera": {"look_from": [0, 0, 0], "look_at": [0, 0, -1], "vertical_fov": 40},
    "background": {"type": "sky", "horizon": [0.5, 0.5, 0.5], "zenith": [0.5, 0.5, 0.5]},
    "objects": [{"type": "sphere", "center": [0, 0, 10], "radius": 1, "material": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}}]})");
  FlatScene<float> scene = test::flatten<float>(sky);
  scene.noise_threshold = 0.01;
  const auto backend = make_cpu_backend<float>(2, Integrator::kMegakernel);  // holds the film
  const RenderedFilm film = render_film(*backend, scene);
  EXPECT_EQ(film.samples_done, 1000u);
  EXPECT_FALSE(film.stopped_early);
  EXPECT_EQ(film.stats.samples, 16u * 8u * kAdaptiveFirstJudgement);
  const LinearImage image = resolve_film(film.pixels(), film.width, film.height);
  for (float v : image.rgb) EXPECT_FLOAT_EQ(v, 0.5f);
}

// The estimate itself: on pixels whose independent samples are drawn with a known spread, the error it reports at
// every judgement is near the true standard error of the displayed mean (the square root's slope at 0.25 is 1;
// averaged over the window, so within about 30 %). Clamped at white, a pixel brighter than white everywhere has no
// error as displayed.
TEST(AdaptiveSampling, ErrorEstimatesTheStandardErrorOfTheDisplayedMean) {
  const u32 width = 40, height = 40;
  for (u32 samples : {16u, 20u, 28u, 64u, 80u}) {
    for (double level : {0.25, 3.0}) {
      test::TestRandom rng(5);
      std::vector<FilmPixel> film(width * height, FilmPixel{});
      for (FilmPixel& p : film)
        for (u32 s = 0; s < samples; ++s) {
          const double v = level + 0.1 * (2 * rng.uniform() - 1);  // standard deviation 0.1 / sqrt(3)
          add_sample(p, SampleResult<double>{Color<double>::splat(v), 1}, s);
        }
      const std::vector<float> errors = adaptive_errors(film, width, height, samples);
      double sum = 0;
      for (float e : errors) sum += e;
      const double expected = level < 1 ? (0.1 / std::sqrt(3.0)) / std::sqrt(static_cast<double>(samples)) : 0.0;
      EXPECT_NEAR(sum / errors.size(), expected, 0.3 * expected + 1e-12) << "level " << level << ", " << samples << " samples";
    }
  }
}

// With stratified samples the estimate follows the stratified mean's error, which is far below that of independent
// samples: pixels whose value is a step in two dimensions of the sampler (a light seen or not, fog crossed or not)
// are judged near their true error, not near the independent samples' (an estimate from odd against even samples,
// which reports the latter, fails this).
TEST(AdaptiveSampling, ErrorFollowsTheStratifiedSamplersError) {
  const u32 width = 32, height = 32;
  const double mean = 0.5 * 0.3 + 0.25 * 0.6;  // the pixels' true value
  const double independent_sigma = std::sqrt(0.25 * 0.3 * 0.7 + 0.0625 * 0.6 * 0.4) * 0.5 / std::sqrt(mean);  // as displayed
  for (u32 samples : {16u, 24u, 32u, 64u, 80u, 128u}) {
    std::vector<FilmPixel> film(width * height, FilmPixel{});
    double actual = 0;
    for (u32 i = 0; i < width * height; ++i) {
      for (u32 s = 0; s < samples; ++s) {
        const SampleRandom random = SampleRandom::make(7, i, s, SamplerKind::kSobol);
        const double v = 0.5 * (random.uniform<double>(0, 3) < 0.3) + 0.25 * (random.uniform<double>(1, 5) < 0.6);
        add_sample(film[i], SampleResult<double>{Color<double>::splat(v), 1}, s);
      }
      const double shown = displayed_brightness(film[i].r / film[i].samples) - displayed_brightness(mean);
      actual += shown * shown;
    }
    actual = std::sqrt(actual / (width * height));
    const std::vector<float> errors = adaptive_errors(film, width, height, samples);
    double estimated = 0;
    for (float e : errors) estimated += e;
    estimated /= errors.size();
    const double independent = independent_sigma / std::sqrt(static_cast<double>(samples));
    std::printf("%u samples: estimated %.4f, true %.4f, independent samples' %.4f\n", samples, estimated, actual, independent);
    EXPECT_LT(estimated, 0.5 * independent) << samples << " samples";
    EXPECT_GT(estimated, 0.7 * actual) << samples << " samples";
  }
}

// The expected image does not move: adaptive renders of the reference scene (glass, metal, a small light, fog) agree
// with the 4096-sample reference in 4x4-pixel block means, within the standard errors of each pixel's own sample
// count (per-sample variances from the reference). Single pixels with rare bright paths are too far from normal to
// test one by one without their own variance (which the film does not keep), at any sampling; blocks are not.
TEST(AdaptiveSampling, ExpectedImageIsTheReference) {
  const LinearImage reference = test::read_pfm(test::reference_image_path());
  const LinearImage variance = test::read_pfm(test::reference_variance_path());
  const u32 samples = PT_TEST_SANITIZED ? 64 : 256, block = 4;
  for (double threshold : {0.005, 0.02}) {
    const FlatScene<float> scene = tiny_adaptive_scene(samples, threshold, 11);
    const auto backend = make_cpu_backend<float>(0, Integrator::kMegakernel);  // holds the film
    const RenderedFilm film = render_film(*backend, scene);
    const LinearImage image = resolve_film(film.pixels(), film.width, film.height);
    double worst = 0, channel_difference[3] = {}, channel_variance[3] = {};
    std::size_t beyond = 0, blocks = 0;
    for (u32 by = 0; by < film.height; by += block)
      for (u32 bx = 0; bx < film.width; bx += block)
        for (int c = 0; c < 3; ++c) {
          double difference = 0, sum_variance = 0;
          for (u32 y = by; y < by + block; ++y)
            for (u32 x = bx; x < bx + block; ++x) {
              const std::size_t pixel = static_cast<std::size_t>(y) * film.width + x, i = 3 * pixel + c;
              difference += image.rgb[i] - reference.rgb[i];
              sum_variance += variance.rgb[i] / film.pixels()[pixel].samples + variance.rgb[i] / test::kReferenceSamples;
            }
          channel_difference[c] += difference;
          channel_variance[c] += sum_variance;
          const double z = std::abs(difference) / (std::sqrt(sum_variance) + 1e-5 * block * block);
          worst = std::max(worst, z);
          beyond += z > 4;
          ++blocks;
        }
    // Normally distributed block differences put 0.006 % of 576 beyond 4 sigma: allow one.
    EXPECT_LE(beyond, 1u) << "threshold " << threshold << ", worst z " << worst;
    EXPECT_LT(worst, 6.0) << "threshold " << threshold;
    for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(channel_difference[c]), 4 * std::sqrt(channel_variance[c])) << "channel " << c;
    std::printf("threshold %.3f, at most %u spp: %.2f of the samples; worst block z %.2f, %zu of %zu beyond 4 sigma; image mean z %.2f %.2f %.2f\n",
                threshold, samples, static_cast<double>(film.stats.samples) / (static_cast<double>(samples) * film.pixels().size()), worst, beyond,
                blocks, channel_difference[0] / std::sqrt(channel_variance[0]), channel_difference[1] / std::sqrt(channel_variance[1]),
                channel_difference[2] / std::sqrt(channel_variance[2]));
  }
}

// On a GPU, with either integrator: the same film on every run, pixels stopped as on the CPU within the rounding of
// the GPU's own arithmetic, and the expected image unchanged against the CPU's adaptive render.
TEST(AdaptiveSampling, GpuRendersAreRepeatableAndAgreeWithTheCpu) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  const FlatScene<float> scene = tiny_adaptive_scene(64, 0.03);
  const std::vector<FilmPixel> cpu = film_of(render_film(*make_cpu_backend<float>(0, Integrator::kMegakernel), scene));
  for (Integrator integrator : {Integrator::kMegakernel, Integrator::kWavefront}) {
    const std::vector<FilmPixel> first = film_of(render_film(*make_backend<float>("cuda", 0, 0, integrator), scene));
    const std::vector<FilmPixel> second = film_of(render_film(*make_backend<float>("cuda", 0, 0, integrator), scene));
    EXPECT_TRUE(test::same_film(first, second));
    std::size_t same_stop = 0;
    u64 cpu_samples = 0, gpu_samples = 0;
    for (std::size_t i = 0; i < cpu.size(); ++i) {
      same_stop += cpu[i].stopped_at == first[i].stopped_at;
      cpu_samples += cpu[i].samples;
      gpu_samples += first[i].samples;
    }
    EXPECT_GE(same_stop, cpu.size() * 95 / 100);
    EXPECT_NEAR(static_cast<double>(gpu_samples), static_cast<double>(cpu_samples), 0.02 * cpu_samples);
    std::printf("cuda %s: %zu of %zu pixels stopped where the CPU stopped them; samples %.4f of the CPU's\n",
                integrator == Integrator::kMegakernel ? "megakernel" : "wavefront", same_stop, cpu.size(),
                static_cast<double>(gpu_samples) / cpu_samples);
  }
#endif
}

#ifdef PT_PATHTRACER_BINARY
// The program: --noise-threshold and the scene's render block take it; a value that is not an error on the display's 0..1 scale is
// refused on one line; an adaptive render stopped by its time limit and resumed from its checkpoint writes the
// image of an uninterrupted one.
TEST(AdaptiveSampling, CommandLineTakesItRefusesNonsenseAndResumesExactly) {
  test::TempDir dir;
  const std::string scene = test::quoted(test::scene_path("tiny.json"));
  for (const char* bad : {"nan", "-0.1", "2", "inf"}) {
    const test::CommandResult r = test::run_pathtracer("render " + scene + " --noise-threshold " + bad + " -o " + test::quoted(dir / "x.pfm"), dir);
    EXPECT_EQ(r.exit_code, 1) << bad;
    EXPECT_NE(r.err.find(std::string("--noise-threshold ") + bad), std::string::npos) << r.err;
    EXPECT_EQ(test::lines_of(r.err).size(), 1u) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.pfm"));
  }
  test::write_text_file(dir / "bad.json", test::replaced(test::read_text_file(test::scene_path("tiny.json")), "\"max_depth\": 8",
                                                         "\"max_depth\": 8, \"noise_threshold\": -1"));
  const test::CommandResult bad_scene = test::run_pathtracer("render " + test::quoted(dir / "bad.json") + " -o " + test::quoted(dir / "x.pfm"), dir);
  EXPECT_EQ(bad_scene.exit_code, 1);
  EXPECT_NE(bad_scene.err.find("noise_threshold"), std::string::npos) << bad_scene.err;

  const std::string common = " --width 32 --height 24 --spp 200 --noise-threshold 0.02 -q";
  ASSERT_EQ(test::run_pathtracer("render " + scene + common + " -o " + test::quoted(dir / "whole.pfm"), dir).exit_code, 0);
  const test::CommandResult part =
      test::run_pathtracer("render " + scene + common + " --time-limit 0.001 --checkpoint " + test::quoted(dir / "c.film") + " -o " + test::quoted(dir / "part.pfm"), dir);
  ASSERT_EQ(part.exit_code, 0) << part.err;
  ASSERT_EQ(test::run_pathtracer("render " + scene + common + " --resume " + test::quoted(dir / "c.film") + " -o " + test::quoted(dir / "rest.pfm"), dir).exit_code, 0);
  const LinearImage whole = test::read_pfm(dir / "whole.pfm"), rest = test::read_pfm(dir / "rest.pfm"), early = test::read_pfm(dir / "part.pfm");
  EXPECT_EQ(whole.rgb, rest.rgb);
  EXPECT_NE(whole.rgb, early.rgb) << "the time limit stopped the first render early";
  // Another threshold is another render: its checkpoint is refused.
  const test::CommandResult other = test::run_pathtracer(
      "render " + scene + " --width 32 --height 24 --spp 200 --noise-threshold 0.05 -q --resume " + test::quoted(dir / "c.film") + " -o " + test::quoted(dir / "o.pfm"), dir);
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.err.find("other settings"), std::string::npos) << other.err;
}
#endif

}  // namespace pt::adaptive_sampling_test
