// Several devices behind one backend: uploads to each, bands of each pass handed out by backends/bands.hpp.
#include "backends/multi_backend.hpp"

#include <algorithm>
#include <functional>
#include <future>

#include <fmt/format.h>

#include "base/number_formats.hpp"

namespace pt {

// A device of this process as a band worker.
template <class T>
class MultiBackend<T>::DeviceWorker final : public BandWorker {
 public:
  DeviceWorker(RenderBackend<T>& backend, std::string label) : backend_(backend), label_(std::move(label)) {}
  std::string name() const override { return label_.empty() ? backend_.name() : label_ + ": " + backend_.name(); }
  bool render_band(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>&) override {
    if (from.data() != into.data()) std::copy(from.begin(), from.end(), into.begin());
    backend_.render_rows(work.first_row, work.row_count, work.first_sample, work.sample_count, into);
    return true;
  }

 private:
  RenderBackend<T>& backend_;
  std::string label_;
};

template <class T>
MultiBackend<T>::MultiBackend(std::vector<std::unique_ptr<RenderBackend<T>>> devices, std::vector<std::unique_ptr<BandWorker>> remote,
                              const std::string& label)
    : devices_(std::move(devices)) {
  for (auto& device : devices_) workers_.push_back(std::make_unique<DeviceWorker>(*device, label));
  for (auto& worker : remote) workers_.push_back(std::move(worker));
  if (workers_.empty()) throw BackendError("no device to render on");
  for (auto& worker : workers_) worker_pointers_.push_back(worker.get());
  shares_.assign(workers_.size(), 0);
  alone_ = devices_.size() == 1 && workers_.size() == 1;
  others_ = workers_.size() > devices_.size();
}

template <class T>
MultiBackend<T>::~MultiBackend() {
  workers_.clear();  // the device workers refer to the devices
}

template <class T>
std::string MultiBackend<T>::name() const {
  std::string names;
  for (const auto& worker : workers_) names += (names.empty() ? "" : "; ") + worker->name();
  return fmt::format("{} devices in bands: {}", workers_.size(), names);
}

template <class T>
void MultiBackend<T>::upload(const FlatScene<T>& scene) {
  // Every device at once: a GPU's upload is mostly copies, which overlap.
  std::vector<std::future<void>> uploads;
  for (auto& device : devices_) uploads.push_back(std::async(std::launch::async, [&scene, &device] { device->upload(scene); }));
  for (auto& upload : uploads) upload.get();
  width_ = scene.params.width;
  height_ = scene.params.height;
  if (alone_)
    film_.clear();
  else
    film_.assign(static_cast<std::size_t>(width_) * height_, FilmPixel{});
  if (others_) next_.assign(film_.size(), FilmPixel{});
  row_costs_.assign(height_, 0.0);
  std::fill(shares_.begin(), shares_.end(), 0);
}

template <class T>
void MultiBackend<T>::render(u32 first_sample, u32 sample_count) {
  if (!alone_) return render_rows(0, height_, first_sample, sample_count, film_);
  devices_[0]->render(first_sample, sample_count);
  shares_[0] += static_cast<u64>(width_) * height_ * sample_count;
}

// With other processes a pass renders into a second film, which replaces the first only once every band is in: a
// stop can then give the pass up at once, dropping what came in, rather than wait for bands elsewhere (mpirun kills
// every rank a second after passing on a SIGTERM). Bands of this process's devices cannot be left, so they are
// kept short.
template <class T>
bool MultiBackend<T>::render_unless(u32 first_sample, u32 sample_count, const std::function<bool()>& stop) {
  if (!others_) return RenderBackend<T>::render_unless(first_sample, sample_count, stop);
  const BandWork work{0, height_, first_sample, sample_count};
  std::vector<u64> pass_shares(workers_.size(), 0);
  if (!render_bands(worker_pointers_, width_, work, film_, next_, min_band_rows(height_, workers_.size()), pass_shares, row_costs_,
                    PassStop{stop, kLongestBandSeconds}))
    return false;
  film_.swap(next_);
  for (std::size_t i = 0; i < shares_.size(); ++i) shares_[i] += pass_shares[i];
  return true;
}

template <class T>
double MultiBackend<T>::pass_seconds() const {
  return others_ ? kPassSecondsWithOthers : RenderBackend<T>::pass_seconds();
}

template <class T>
void MultiBackend<T>::render_rows(u32 first_row, u32 row_count, u32 first_sample, u32 sample_count, std::span<FilmPixel> band) {
  if (first_row + row_count > height_) throw BackendError("a band of rows outside the image");
  const BandWork work{first_row, row_count, first_sample, sample_count};
  render_bands(worker_pointers_, width_, work, band, band, min_band_rows(row_count, workers_.size()), shares_, row_costs_);
}

template <class T>
void MultiBackend<T>::read_film(std::vector<FilmPixel>& pixels) {
  if (alone_)
    devices_[0]->read_film(pixels);
  else
    pixels = film_;
}

template <class T>
void MultiBackend<T>::write_film(std::span<const FilmPixel> pixels) {
  if (alone_) return devices_[0]->write_film(pixels);
  if (pixels.size() != film_.size()) throw BackendError("a film of another size cannot be resumed");
  std::copy(pixels.begin(), pixels.end(), film_.begin());
}

// One device judges its own film; bands of several devices or processes come together in the film held here.
template <class T>
std::size_t MultiBackend<T>::stop_clean_pixels(u32 width, u32 height, u32 samples_done, double threshold) {
  if (alone_) return devices_[0]->stop_clean_pixels(width, height, samples_done, threshold);
  return judge_film_on_host(film_, width, height, samples_done, threshold);
}

template <class T>
std::span<const FilmPixel> MultiBackend<T>::film_on_host(std::vector<FilmPixel>& copy) {
  if (alone_) return devices_[0]->film_on_host(copy);
  return film_;
}

template <class T>
std::optional<double> MultiBackend<T>::device_seconds() const {
  if (alone_) return devices_[0]->device_seconds();
  return std::nullopt;
}

template <class T>
std::vector<std::pair<std::string, double>> MultiBackend<T>::stage_seconds() const {
  if (alone_) return devices_[0]->stage_seconds();
  return {};
}

template <class T>
u64 MultiBackend<T>::saturations() const {
  u64 total = 0;
  for (const auto& device : devices_) total += device->saturations();
  return total;
}

template <class T>
std::vector<std::pair<std::string, u64>> MultiBackend<T>::work_shares() const {
  std::vector<std::pair<std::string, u64>> out;
  for (std::size_t i = 0; i < workers_.size(); ++i) out.emplace_back(workers_[i]->name(), shares_[i]);
  return out;
}

#define PT_INSTANTIATE_MULTI_BACKEND(...) template class MultiBackend<__VA_ARGS__>;
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_MULTI_BACKEND)

}  // namespace pt
