// The bidirectional integrator on any device, sample after sample: either one launch over the image that traces a
// light subpath and a camera subpath per pixel and joins them (kernel/bidirectional.hpp, BidirectionalSample), or the
// staged schedule, four launches over a band of rows at a time (light subpaths; camera subpaths; connections;
// gathering); then one that folds that sample's splats into the film. Both make the same image bit for bit. Vertex
// connection and merging (VCM) runs in bands always (a band's light subpaths are a pass's pool), with a grid of the
// band's light vertices built between the light and the camera subpaths: the camera side then runs as stages (the
// connections' launch also merges) or, on the host, in one launch (VertexMergingCameraSample); the same film either way.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "base/render_settings.hpp"
#include "integrators/device.hpp"
#include "kernel/bidirectional.hpp"

namespace pt {

// The staged schedule's buffers for a band: a GPU wants a band of a few hundred thousand pixels to fill its threads;
// the host keeps a band near its caches.
inline constexpr std::size_t kGpuBidirectionalBandBytes = std::size_t{2} << 30;
inline constexpr std::size_t kHostBidirectionalBandBytes = std::size_t{8} << 20;

// Vertex merging's band is its pool of light subpaths, the same on every device (the image depends on it): as many whole
// rows as this many bytes of buffers hold.
inline constexpr std::size_t kMergingBandBytes = std::size_t{256} << 20;

// How fast the merging radius shrinks from pass to pass (Knaus and Zwicker 2011, as in SmallVCM): pass s (from 0) merges
// within r0 (s + 1)^((alpha - 1) / 2), so that bias and variance both vanish as passes are added.
inline constexpr double kMergingAlpha = 0.75;

// The merging radius of pass `sample`, from the first pass's.
inline double merging_radius(double first_radius, u32 sample) {
  return first_radius * std::pow(static_cast<double>(sample) + 1.0, (kMergingAlpha - 1.0) / 2.0);
}

// A pass's merging parameters for `light_subpaths` light subpaths merged within `radius`.
template <class T>
MergeParams<T> merge_params(double radius, u32 light_subpaths) {
  const double eta = std::numbers::pi * radius * radius * light_subpaths;
  return MergeParams<T>{T(radius), T(eta * eta), T(1 / (eta * eta)), T(1 / eta)};
}

// Whether the staged schedule runs: as asked, or by default where the device is not the host and some light can start a
// subpath (BENCHMARKS.md: on a GPU it is the faster, on a CPU one kernel a sample is, and so it is on a GPU where the
// only light is the background: then there is nothing to connect, and the stages only add their launches).
template <Device D>
bool bidirectional_staged(const D& device, BidirectionalSchedule schedule, bool light_subpaths) {
  return schedule == BidirectionalSchedule::kAuto ? !device.host() && light_subpaths : schedule == BidirectionalSchedule::kStaged;
}

template <Device D, class T>
class BidirectionalIntegrator {
 public:
  // `light_subpaths`: whether any light of the scene can start a light subpath (an emitting shape). `merge_radius`:
  // the first pass's merging radius (VCM); 0 for bidirectional path tracing.
  BidirectionalIntegrator(D& device, const SceneView<T>& scene, FilmPixel* film, BidirectionalSchedule schedule, bool light_subpaths,
                          double merge_radius = 0)
      : device_(device), scene_(scene), film_(film), merge_radius_(merge_radius) {
    const RenderParams<T>& params = scene.params;
    if (params.max_depth > kMaxBidirectionalDepth)
      throw BackendError("bdpt traces paths of at most " + std::to_string(kMaxBidirectionalDepth) + " bounces; this render asks for " +
                         std::to_string(params.max_depth) + " (--depth)");
    const std::size_t bytes = 3 * sizeof(u64) * static_cast<std::size_t>(params.width) * params.height;
    splats_ = static_cast<u64*>(memory_.allocate(bytes, "allocating the splat sums"));
    device_.clear(splats_, bytes, "clearing the splat sums");
    // Merging always runs in bands (its pool of light subpaths); its camera side in one launch where one kernel a sample
    // is the device's faster (the host), else in stages.
    merging_in_one_launch_ = merge_radius_ > 0 && !bidirectional_staged(device_, schedule, true);
    if (merge_radius_ > 0)
      allocate_band(kMergingBandBytes);
    else if (bidirectional_staged(device_, schedule, light_subpaths))
      allocate_band(device_.host() ? kHostBidirectionalBandBytes : kGpuBidirectionalBandBytes);
  }

  // Adds samples [first_sample, first_sample + sample_count) of every pixel to the film, light tracing's splats
  // included, each sample's after its own contributions.
  void render(u32 first_sample, u32 sample_count) {
    const u32 width = scene_.params.width, height = scene_.params.height;
    for (u32 s = first_sample; s < first_sample + sample_count; ++s) {
      const SplatFilm splats{splats_, width};
      if (band_rows_ == 0) {
        stage(kSamples, [&] { device_.launch_image("launching the bidirectional kernel", width, height, BidirectionalSample<T>{scene_, film_, splats, s}); });
      } else {
        for (u32 first_row = 0; first_row < height; first_row += band_rows_) {
          const u32 rows = std::min(band_rows_, height - first_row);
          band_.first_row = first_row;
          band_.pixels = rows * width;
          if (merge_radius_ > 0) {
            const double radius = merging_radius(merge_radius_, s);
            scene_.params.merging = merge_params<T>(radius, band_.pixels);
            band_.grid.cell_size = T(2 * radius);
          }
          stage(kLightSubpaths,
                [&] { device_.launch_image("launching the light subpaths", width, rows, BidirectionalLightSubpaths<T>{scene_, band_, splats, s}); });
          if (merge_radius_ > 0) stage(kMergeGrid, [&] { build_merge_grid(); });
          if (merging_in_one_launch_) {
            stage(kCameraSubpaths, [&] {
              device_.launch_image("launching the merging camera subpaths", width, rows, VertexMergingCameraSample<T>{scene_, band_, film_, s});
            });
            continue;
          }
          stage(kCameraSubpaths,
                [&] { device_.launch_image("launching the camera subpaths", width, rows, BidirectionalCameraSubpaths<T>{scene_, band_, s}); });
          // The host waits here for the queue's length.
          u32 queued = 0;
          device_.copy_to_host(&queued, band_.connect_length, sizeof(u32), "reading the bidirectional connection queue");
          device_.clear(band_.connect_length, sizeof(u32), "clearing the bidirectional connection queue");
          stage(kConnections, [&] { device_.launch("launching the bidirectional connections", queued, BidirectionalConnect<T>{scene_, band_, s}); });
          stage(kGathering, [&] { device_.launch("launching the bidirectional gathering", band_.pixels, BidirectionalGather<T>{band_, film_, width, s}); });
        }
      }
      stage(kFolding, [&] { device_.launch("folding the splats", width * height, FoldSplats{film_, splats_}); });
    }
    device_.synchronise("running the bidirectional kernel");
  }

  double seconds() const {
    double total = 0;
    for (double s : seconds_) total += s;
    return total;
  }

  // Seconds spent in each launch of the schedule so far (where the device times them).
  std::vector<std::pair<std::string, double>> stage_seconds() const {
    std::vector<std::pair<std::string, double>> out;
    for (u32 i = 0; i < kStages; ++i)
      if (i == kFolding || ((band_rows_ == 0) == (i == kSamples) && (i != kMergeGrid || merge_radius_ > 0) &&
                            (!merging_in_one_launch_ || (i != kConnections && i != kGathering))))
        out.emplace_back(kStageNames[i], seconds_[i]);
    return out;
  }

 private:
  // The grid of the band's light vertices, built on the device (MergeGridPlace, MergeGridScan and MergeGridSort,
  // kernel/bidirectional.hpp).
  void build_merge_grid() {
    const MergeGrid<T>& grid = band_.grid;
    using Scan = MergeGridScan<T>;
    device_.clear(grid.cursor, grid.cells * sizeof(u32), "clearing the merging grid");
    device_.launch("counting the light vertices to merge", band_.pixels, MergeGridPlace<T>{band_, false});
    device_.launch("summing the merging grid's counts", grid.runs, Scan{grid, Scan::kRunSums});
    device_.launch("summing the merging grid's counts", 1, Scan{grid, Scan::kRunStarts});
    device_.launch("summing the merging grid's counts", grid.runs, Scan{grid, Scan::kCellStarts});
    device_.launch("placing the light vertices to merge", band_.pixels, MergeGridPlace<T>{band_, true});
    device_.launch("sorting the merging grid", grid.cells, MergeGridSort<T>{band_});
  }

  // Buffers for as many whole rows as `budget` bytes hold (at least one).
  void allocate_band(std::size_t budget) {
    const u32 width = scene_.params.width, height = scene_.params.height, depth = scene_.params.max_depth;
    const bool merging = merge_radius_ > 0;
    // Merging also keeps the vertex a light subpath reaches last: a camera vertex can take it as its own.
    const u32 light_slots = merging ? std::max(depth, 2u) - 1 : std::max(depth, 3u) - 2;
    camera_slots_ = std::max(depth, 2u) - 1;
    // Merging: a place and a position for each light vertex in the grid, and about two cells a pixel.
    const std::size_t grid_per_pixel = merging ? light_slots * (sizeof(u32) + sizeof(Vec3<T>)) + 4 * sizeof(u32) : 0;
    const std::size_t per_pixel = light_slots * sizeof(LightVertex<T>) + camera_slots_ * (sizeof(CameraVertex<T>) + sizeof(ConnectionSum<T>) + sizeof(u32)) +
                                  sizeof(SampleResult<T>) + 2 * sizeof(u32) + grid_per_pixel;
    band_rows_ = static_cast<u32>(std::clamp<std::size_t>(budget / (per_pixel * width), 1, height));
    // A camera vertex's place in the band's buffers (slot x capacity + pixel) is queued as a 32-bit number.
    while (band_rows_ > 1 && static_cast<std::size_t>(band_rows_) * width * camera_slots_ > 0xFFFFFFFFull) band_rows_ /= 2;
    const std::size_t capacity = static_cast<std::size_t>(band_rows_) * width;
    band_.capacity = static_cast<u32>(capacity);
    band_.light_vertices = allocate<LightVertex<T>>(capacity * light_slots);
    // A pixel's light vertices together where one launch reads them pixel by pixel (the host's merging); slot by slot
    // for the stages, whichever device runs them, so that the host's tests of the staged schedule read them as a GPU does.
    band_.light_pixel_stride = merging_in_one_launch_ ? light_slots : 1;
    band_.light_slot_stride = merging_in_one_launch_ ? static_cast<u32>(1) : static_cast<u32>(capacity);
    band_.direct = allocate<SampleResult<T>>(capacity);
    band_.light_counts = allocate<u32>(capacity);
    // (The band's rows are counted with the camera side's buffers either way: they set merging's pool of light subpaths.)
    if (!merging_in_one_launch_) {
      band_.camera_vertices = allocate<CameraVertex<T>>(capacity * camera_slots_);
      band_.connections = allocate<ConnectionSum<T>>(capacity * camera_slots_);
      band_.camera_counts = allocate<u32>(capacity);
      band_.connect_queue = allocate<u32>(capacity * camera_slots_);
    }
    band_.connect_length = allocate<u32>(1);
    device_.clear(band_.connect_length, sizeof(u32), "clearing the bidirectional connection queue");
    if (merging) {
      MergeGrid<T>& grid = band_.grid;
      grid.cells = std::bit_ceil(static_cast<u32>(std::max<std::size_t>(capacity * 2, 2)));
      grid.starts = allocate<u32>(grid.cells + 1);
      grid.cursor = allocate<u32>(grid.cells);
      grid.entries = allocate<u32>(capacity * light_slots);
      grid.positions = allocate<Vec3<T>>(capacity * light_slots);
      grid.runs = std::max(grid.cells / kMergeGridRun, 1u);
      grid.run_starts = allocate<u32>(grid.runs);
    }
  }

  template <class E>
  E* allocate(std::size_t count) {
    return static_cast<E*>(memory_.allocate(count * sizeof(E), "allocating the bidirectional band"));
  }

  enum Stage : u32 { kSamples, kLightSubpaths, kMergeGrid, kCameraSubpaths, kConnections, kGathering, kFolding, kStages };
  static constexpr std::array<const char*, kStages> kStageNames{"samples",     "light subpaths", "merging grid", "camera subpaths",
                                                                "connections", "gathering",      "splats"};

  template <class Launch>
  void stage(Stage which, const Launch& launch) {
    const typename D::Timer timer = device_.start_timer();
    launch();
    device_.stop_timer(timer, &seconds_[which]);
  }

  D& device_;
  SceneView<T> scene_;
  FilmPixel* film_;
  DeviceAllocations<D> memory_{device_};
  u64* splats_ = nullptr;
  BidirectionalBand<T> band_{};
  u32 band_rows_ = 0, camera_slots_ = 0;  // rows a band holds (0: one kernel a sample); camera vertex slots a pixel
  double merge_radius_ = 0;                // the first pass's merging radius; 0: no merging
  bool merging_in_one_launch_ = false;     // merging's camera side: VertexMergingCameraSample instead of stages 1b to 3
  std::array<double, kStages> seconds_{};
};

}  // namespace pt
