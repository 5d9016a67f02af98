// Checks the length of render passes, that a pass shared out in bands with a worker of another process gives the
// image of one device (the worker stands in for an MPI rank, rendering in this process), and that a pass given up
// on a stop leaves the film as it was before it.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "backends/multi_backend.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

TEST(PassLength, AimsAtTheBackendsPassSeconds) {
  // 10 samples took 1 s: 0.1 s a sample.
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 0.5), 5u);
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0), 20u);
}

TEST(PassLength, GrowsAtMostFourfoldAndNeverBelowOneSample) {
  EXPECT_EQ(next_pass_samples(0.01, 10, 1, 2.0), 4u);  // 2000 wanted after one fast pass of 1 sample
  EXPECT_EQ(next_pass_samples(10.0, 1, 1, 0.5), 1u);   // a sample takes longer than a pass
  EXPECT_EQ(next_pass_samples(0.0, 0, 3, 0.5), 6u);    // nothing measured yet: twice the last
}

TEST(PassLength, EndsNearTheTimeLimit) {
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0, 0.35), 3u);  // 3.5 samples fit
  EXPECT_EQ(next_pass_samples(1.0, 10, 10, 2.0, 1e-9), 1u);  // the limit is reached: one more sample at least
}

// A worker elsewhere, as an MPI rank is to rank 0: it gets each band's film, adds the band's samples with its own
// device, and hands the film back. A band handed to it once a stop is asked for stays "on its way": it is left.
// From sample `late_sample` on it counts the bands it renders, or, where `holds_late_bands`, holds each band until
// a stop and leaves it, as a rank does whose band is still under way when the stop comes.
class OtherProcessWorker final : public BandWorker {
 public:
  OtherProcessWorker(const FlatScene<float>& scene, u32 width) : device_(make_cpu_backend<float>(1)), width_(width) { device_->upload(scene); }
  std::string name() const override { return "stand-in rank"; }
  bool leaves_bands() const override { return true; }
  bool render_band(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>& stop) override {
    EXPECT_EQ(from.size(), static_cast<std::size_t>(work.row_count) * width_);
    const bool late = work.first_sample >= late_sample;
    if (late && holds_late_bands) {
      while (!stop()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      return false;
    }
    if (stop()) return false;
    if (lost_after >= 0 && bands >= lost_after) {
      EXPECT_FALSE(is_lost.load()) << "a band was given to a lost worker";
      is_lost = true;
      throw WorkerLost("stand-in rank has not answered");
    }
    std::vector<FilmPixel> there(from.begin(), from.end());  // the band travels by copy, as a message does
    device_->render_rows(work.first_row, work.row_count, work.first_sample, work.sample_count, there);
    std::copy(there.begin(), there.end(), into.begin());
    ++bands;
    if (late) ++late_bands;
    return true;
  }
  std::atomic<int> bands = 0, late_bands = 0;
  u32 late_sample = ~0u;
  bool holds_late_bands = false;
  int lost_after = -1;  // from this many bands on, each band given is given up: the rank stopped answering
  std::atomic<bool> is_lost = false;
  bool lost() const override { return is_lost.load(); }

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

// A rank lost mid-render (it threw WorkerLost, as a rank that does not answer by its band's deadline does) has its
// band rendered by the others, gets no band after, and the image is still bitwise that of one device.
TEST(BandsWithAnotherProcess, LostRanksBandGoesToTheOthersAndTheImageIsTheSame) {
  SceneDescription description = load_scene_file(test::scene_path("tiny.json"));
  description.render.samples_per_pixel = 6;
  const FlatScene<float> scene = test::flatten<float>(description);
  const std::unique_ptr<RenderBackend<float>> one = make_cpu_backend<float>(2);
  const RenderedFilm alone = render_film(*one, scene);
  for (const int lost_after : {0, 1}) {
    SCOPED_TRACE(lost_after);
    std::vector<std::unique_ptr<RenderBackend<float>>> devices;
    devices.push_back(make_cpu_backend<float>(1));
    std::vector<std::unique_ptr<BandWorker>> remote;
    auto worker = std::make_unique<OtherProcessWorker>(scene, scene.params.width);
    OtherProcessWorker* rank = worker.get();
    rank->lost_after = lost_after;
    remote.push_back(std::move(worker));
    MultiBackend<float> shared(std::move(devices), std::move(remote));
    const RenderedFilm together = render_film(shared, scene);
    const std::vector<FilmPixel> a(alone.pixels().begin(), alone.pixels().end());
    const std::vector<FilmPixel> b(together.pixels().begin(), together.pixels().end());
    EXPECT_TRUE(test::same_film(a, b));
    EXPECT_EQ(rank->bands, lost_after);
    EXPECT_TRUE(rank->is_lost.load());
  }
}

// The film of `samples` samples per pixel rendered by one device.
std::vector<FilmPixel> one_device_film(const FlatScene<float>& scene, u32 samples) {
  FlatScene<float> part = scene;
  part.samples_per_pixel = samples;
  const std::unique_ptr<RenderBackend<float>> one = make_cpu_backend<float>(2);
  const RenderedFilm film = render_film(*one, part);
  return {film.pixels().begin(), film.pixels().end()};
}

TEST(PassGivenUp, LeavesTheFilmOfThePassesBeforeAndResumesToTheSameImage) {
  SceneDescription description = load_scene_file(test::scene_path("tiny.json"));
  description.render.samples_per_pixel = 40;
  const FlatScene<float> scene = test::flatten<float>(description);
  // Two stand-in ranks (so that what happens is certain whatever the threads' timing).
  const auto two_ranks = [&](OtherProcessWorker** first, OtherProcessWorker** second) {
    std::vector<std::unique_ptr<BandWorker>> remote;
    remote.push_back(std::make_unique<OtherProcessWorker>(scene, scene.params.width));
    remote.push_back(std::make_unique<OtherProcessWorker>(scene, scene.params.width));
    *first = static_cast<OtherProcessWorker*>(remote[0].get());
    *second = static_cast<OtherProcessWorker*>(remote[1].get());
    return std::make_unique<MultiBackend<float>>(std::vector<std::unique_ptr<RenderBackend<float>>>{}, std::move(remote));
  };
  OtherProcessWorker *a = nullptr, *b = nullptr;
  const std::unique_ptr<MultiBackend<float>> shared = two_ranks(&a, &b);
  EXPECT_GT(shared->pass_seconds(), 0.5);  // passes that can be given up may be long
  // Passes of 1, 4 and 16 samples (each at most 4 times the last). In the third, from sample 5 on, rank b holds its
  // band and rank a renders one band, after which the stop comes: the pass is given up with one band in and the
  // rest not (every band is at most a quarter of what is left).
  a->late_sample = b->late_sample = 5;
  b->holds_late_bands = true;
  RenderControl control;
  control.stop_requested = [a] { return a->late_bands.load() >= 1; };
  const RenderedFilm stopped = render_film(*shared, scene, {}, control);
  ASSERT_TRUE(stopped.stopped_early);
  ASSERT_EQ(stopped.samples_done, 5u);
  EXPECT_EQ(a->late_bands.load(), 1);
  const std::vector<FilmPixel> film(stopped.pixels().begin(), stopped.pixels().end());
  EXPECT_TRUE(test::same_film(film, one_device_film(scene, 5)));

  // Resumed in bands again, it is the image of one uninterrupted device.
  const std::unique_ptr<MultiBackend<float>> again = two_ranks(&a, &b);
  RenderControl resume;
  resume.start_film = film;
  resume.start_samples = stopped.samples_done;
  const RenderedFilm resumed = render_film(*again, scene, {}, resume);
  EXPECT_FALSE(resumed.stopped_early);
  const std::vector<FilmPixel> whole(resumed.pixels().begin(), resumed.pixels().end());
  EXPECT_TRUE(test::same_film(whole, one_device_film(scene, 40)));
}

// Records the bands it is given and renders nothing.
class RecordingWorker final : public BandWorker {
 public:
  explicit RecordingWorker(bool leaves = false) : leaves_(leaves) {}
  std::string name() const override { return "recorder"; }
  bool leaves_bands() const override { return leaves_; }
  bool render_band(const BandWork& work, std::span<const FilmPixel>, std::span<FilmPixel>, const std::function<bool()>&) override {
    bands.push_back(work);
    return true;
  }
  std::vector<BandWork> bands;

 private:
  bool leaves_;
};

// Row costs (seconds a sample) of 1 to 5 units of 2^-10 s, sums of which are exact.
std::vector<double> uneven_row_costs(u32 height) {
  std::vector<double> costs(height);
  for (u32 y = 0; y < height; ++y) costs[y] = (1 + y % 5) / 1024.0;
  return costs;
}

TEST(PassGivenUp, NoBandIsHandedOutAfterTheStop) {
  RecordingWorker worker;
  BandWorker* const workers[] = {&worker};
  const u32 width = 4, height = 64;
  std::vector<FilmPixel> from(width * height), into(width * height);
  std::vector<u64> shares(1, 0);
  const BandWork work{0, height, 0, 8};
  std::vector<double> costs = uneven_row_costs(height);  // each call measures the recorder's bands: a copy each time
  EXPECT_TRUE(render_bands(workers, width, work, from, into, 1, shares, costs, PassStop{[] { return false; }, 0.05}));
  ASSERT_GT(worker.bands.size(), 3u);
  worker.bands.clear();
  costs = uneven_row_costs(height);
  EXPECT_FALSE(render_bands(workers, width, work, from, into, 1, shares, costs, PassStop{[&worker] { return worker.bands.size() >= 2; }, 0.05}));
  EXPECT_EQ(worker.bands.size(), 2u);
}

TEST(PassGivenUp, BandsThatMayHoldUpAStopAreCutShort) {
  RecordingWorker worker;
  BandWorker* const workers[] = {&worker};
  const u32 width = 4, height = 64;
  std::vector<FilmPixel> from(width * height), into(width * height);
  std::vector<u64> shares(1, 0);
  const BandWork work{0, height, 0, 8};
  // Unbounded, the first band is half the pass's cost (one worker): far above the bound below.
  std::vector<double> costs = uneven_row_costs(height);
  render_bands(workers, width, work, from, into, 1, shares, costs);
  ASSERT_GT(worker.bands.front().expected_seconds, 0.5);
  worker.bands.clear();
  costs = uneven_row_costs(height);
  EXPECT_TRUE(render_bands(workers, width, work, from, into, 1, shares, costs, PassStop{[] { return false; }, 0.05}));
  u32 rows = 0;
  for (const BandWork& band : worker.bands) {
    EXPECT_LE(band.expected_seconds, 0.05);
    EXPECT_EQ(band.first_row, rows);
    rows += band.row_count;
  }
  EXPECT_EQ(rows, height);  // every row, in order, in bands within the bound

  // A worker that can leave its bands on a stop does not hold it up: its bands are not cut.
  RecordingWorker elsewhere(true);
  BandWorker* const others[] = {&elsewhere};
  costs = uneven_row_costs(height);
  EXPECT_TRUE(render_bands(others, width, work, from, into, 1, shares, costs, PassStop{[] { return false; }, 0.05}));
  EXPECT_GT(elsewhere.bands.front().expected_seconds, 0.5);
}

}  // namespace
}  // namespace pt
