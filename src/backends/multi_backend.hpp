// Several devices, and other processes of an MPI run, rendering one image: a backend whose film is on the host and
// whose passes are split into bands of rows handed out as each device becomes free (docs/distributed.md).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "backends/backend.hpp"
#include "backends/bands.hpp"

namespace pt {

template <class T>
class MultiBackend final : public RenderBackend<T> {
 public:
  // `devices` render in this process (each with its own backend); `remote` are workers elsewhere, which have the
  // scene already (the other ranks of an MPI run). `label`, where not empty, goes before the devices' names (this
  // rank and its host, beside the other ranks).
  explicit MultiBackend(std::vector<std::unique_ptr<RenderBackend<T>>> devices, std::vector<std::unique_ptr<BandWorker>> remote = {},
                        const std::string& label = {});
  ~MultiBackend() override;

  std::string name() const override;
  void upload(const FlatScene<T>& scene) override;
  void render(u32 first_sample, u32 sample_count) override;
  bool render_unless(u32 first_sample, u32 sample_count, const std::function<bool()>& stop) override;
  double pass_seconds() const override;
  void render_rows(u32 first_row, u32 row_count, u32 first_sample, u32 sample_count, std::span<FilmPixel> band) override;
  // By the first device alone: the layers pass is one camera ray a sample, far cheaper than the image's.
  void render_layers(u32 first_sample, u32 sample_count, std::span<LayerPixel> layers) override {
    if (devices_.empty()) throw BackendError("no device of this process to render the layers on");
    devices_.front()->render_layers(first_sample, sample_count, layers);
  }
  void read_film(std::vector<FilmPixel>& pixels) override;
  void write_film(std::span<const FilmPixel> pixels) override;
  std::size_t stop_clean_pixels(u32 width, u32 height, u32 samples_done, double threshold) override;
  std::span<const FilmPixel> film_on_host(std::vector<FilmPixel>& copy) override;
  std::optional<double> device_seconds() const override;
  std::vector<std::pair<std::string, double>> stage_seconds() const override;
  u64 saturations() const override;
  std::vector<std::pair<std::string, u64>> work_shares() const override;

 private:
  class DeviceWorker;
  std::vector<std::unique_ptr<RenderBackend<T>>> devices_;
  std::vector<std::unique_ptr<BandWorker>> workers_;  // the devices' first, then the remote ones
  std::vector<BandWorker*> worker_pointers_;
  std::vector<u64> shares_;  // pixel-samples each worker rendered since the upload
  // One device and no one else: nothing to share out, so the film stays on the device and passes go to it whole
  // (no band copies: `--device all` on a machine of one GPU costs what `--device 0` does).
  bool alone_ = false;
  // Passes where other processes take part: each sends the whole film out and back in bands, so a pass of half a
  // second cost rank 1 of two on a 2-core machine 7.5 % of its time; passes of 2 s a quarter of that (BENCHMARKS.md).
  static constexpr double kPassSecondsWithOthers = 2.0;
  // The longest band when a pass may be given up: a stop waits for bands of this process's devices in flight, and
  // rank 0 must still save and write its image before mpirun's kill a second after the signal.
  static constexpr double kLongestBandSeconds = 0.25;
  bool others_ = false;            // other processes take bands: passes may be given up (render_unless)
  std::vector<FilmPixel> film_;    // the whole image's sums, but when alone
  std::vector<FilmPixel> next_;    // with others: the film of the pass under way, which replaces film_ once complete
  std::vector<double> row_costs_;  // seconds a sample of each row took when last rendered (render_bands)
  u32 width_ = 0, height_ = 0;
};

}  // namespace pt
