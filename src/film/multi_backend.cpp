// Several devices behind one backend: uploads to each, bands of each pass handed out by film/bands.hpp.
#include "film/multi_backend.hpp"

#include <algorithm>
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
  void render_band(const BandWork& work, std::span<FilmPixel> band) override {
    backend_.render_rows(work.first_row, work.row_count, work.first_sample, work.sample_count, band);
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
  film_.assign(static_cast<std::size_t>(width_) * height_, FilmPixel{});
  std::fill(shares_.begin(), shares_.end(), 0);
}

template <class T>
void MultiBackend<T>::render(u32 first_sample, u32 sample_count) {
  render_rows(0, height_, first_sample, sample_count, film_);
}

template <class T>
void MultiBackend<T>::render_rows(u32 first_row, u32 row_count, u32 first_sample, u32 sample_count, std::span<FilmPixel> band) {
  if (first_row + row_count > height_) throw BackendError("a band of rows outside the image");
  const BandWork work{first_row, row_count, first_sample, sample_count};
  render_bands(worker_pointers_, width_, work, band, band_rows_for(row_count, workers_.size()), shares_);
}

template <class T>
void MultiBackend<T>::write_film(std::span<const FilmPixel> pixels) {
  if (pixels.size() != film_.size()) throw BackendError("a film of another size cannot be resumed");
  std::copy(pixels.begin(), pixels.end(), film_.begin());
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
