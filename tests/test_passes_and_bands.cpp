// Checks the length of render passes, and that a pass shared out in bands with a worker of another process gives
// the image of one device (the worker stands in for an MPI rank, rendering in this process).
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "film/multi_backend.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

TEST(PassLength, AimsAtTheBackendsPassSeconds) {
  // 10 samples took 1 s: 0.1 s a sample.
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 0.5), 5u);
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0), 20u);
}

TEST(PassLength, GrowsAtMostFourfoldAndNeverBelowOneSample) {
  EXPECT_EQ(next_pass_samples(0.01, 10, 1, 2.0), 4u);   // 2000 wanted after one fast pass of 1 sample
  EXPECT_EQ(next_pass_samples(10.0, 1, 1, 0.5), 1u);    // a sample takes longer than a pass
  EXPECT_EQ(next_pass_samples(0.0, 0, 3, 0.5), 6u);     // nothing measured yet: twice the last
}

TEST(PassLength, EndsNearTheTimeLimit) {
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0, 0.35), 3u);  // 3.5 samples fit
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0, 1e-9), 1u);  // the limit is reached: one more sample at least
}

// A worker elsewhere, as an MPI rank is to rank 0: it gets each band's film, adds the band's samples with its own
// device, and hands the film back.
class OtherProcessWorker final : public BandWorker {
 public:
  OtherProcessWorker(const FlatScene<float>& scene, u32 width) : device_(make_cpu_backend<float>(1)), width_(width) {
    device_->upload(scene);
  }
  std::string name() const override { return "stand-in rank"; }
  void render_band(const BandWork& work, std::span<FilmPixel> band) override {
    ASSERT_EQ(band.size(), static_cast<std::size_t>(work.row_count) * width_);
    ++bands;
    const std::vector<FilmPixel> sent(band.begin(), band.end());  // the band travels by copy, as a message does
    std::vector<FilmPixel> there = sent;
    device_->render_rows(work.first_row, work.row_count, work.first_sample, work.sample_count, there);
    std::copy(there.begin(), there.end(), band.begin());
  }
  int bands = 0;

 private:
  std::unique_ptr<RenderBackend<float>> device_;
  u32 width_;
};

TEST(BandsWithAnotherProcess, ImageIsBitwiseThatOfOneDevice) {
  SceneDescription description = load_scene_file(test::scene_path("tiny.json"));
  description.render.samples_per_pixel = 6;
  const FlatScene<float> scene = test::flatten<float>(description);
  const std::unique_ptr<RenderBackend<float>> one = make_cpu_backend<float>(2);
  const RenderedFilm alone = render_film(*one, scene);

  std::vector<std::unique_ptr<RenderBackend<float>>> devices;
  devices.push_back(make_cpu_backend<float>(1));
  std::vector<std::unique_ptr<BandWorker>> remote;
  auto worker = std::make_unique<OtherProcessWorker>(scene, scene.params.width);
  OtherProcessWorker* rank = worker.get();
  remote.push_back(std::move(worker));
  MultiBackend<float> shared(std::move(devices), std::move(remote));
  const RenderedFilm together = render_film(shared, scene);

  const std::vector<FilmPixel> a(alone.pixels().begin(), alone.pixels().end());
  const std::vector<FilmPixel> b(together.pixels().begin(), together.pixels().end());
  EXPECT_TRUE(test::same_film(a, b));
  EXPECT_GT(rank->bands, 0);  // the stand-in rank did render some of it
  u64 samples = 0;
  for (const auto& [name, share] : shared.work_shares()) samples += share;
  EXPECT_EQ(samples, static_cast<u64>(scene.params.width) * scene.params.height * 6);
}

}  // namespace
}  // namespace pt
