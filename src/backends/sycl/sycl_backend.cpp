// The SYCL backend: a thin host layer over standard SYCL 2020 (USM device allocations, an in-order queue, a
// parallel_for over the image per sample, or one per wavefront stage over its queue) running the shared kernel
// headers. Compiled by a SYCL compiler only.

// The SYCL header comes first: the kernel headers choose their SYCL paths (atomics, no x86 builtins in code that
// may be compiled for a GPU) from whether it was seen, and sycl_backend.hpp already reaches them.
#include <sycl/sycl.hpp>

#include "backends/sycl/sycl_backend.hpp"

#if !defined(PT_SYCL_KERNELS)
#error "the kernel headers were reached before the SYCL header: they would take their CPU-only paths"
#endif

#include <algorithm>
#include <chrono>
#include <deque>
#include <functional>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "backends/wavefront_schedule.hpp"
#include "kernel/integrator.hpp"

namespace pt {

namespace {

// Runtime messages may span several lines; an error of this program is one line.
std::string one_line(const std::string& text) {
  std::string out;
  bool pending_break = false;
  for (const char c : text) {
    if (c == '\n' || c == '\r') {
      pending_break = !out.empty();
      continue;
    }
    if (pending_break) out += "; ";
    pending_break = false;
    out += c;
  }
  return out;
}

std::string describe(const sycl::device& device) {
  const char* kind = device.is_gpu() ? "gpu" : device.is_cpu() ? "cpu" : device.is_accelerator() ? "accelerator" : "device";
  std::string text = fmt::format("{} ({}, {}; {} compute units", device.get_info<sycl::info::device::name>(), kind,
                                 device.get_platform().get_info<sycl::info::platform::name>(),
                                 device.get_info<sycl::info::device::max_compute_units>());
  // Host devices may report no real limit (AdaptiveCpp's OpenMP device says 2^64 bytes); only a real size helps.
  const double gib = static_cast<double>(device.get_info<sycl::info::device::global_mem_size>()) / 1073741824.0;
  if (gib > 0 && gib < 1e6) text += fmt::format(", {:.1f} GiB", gib);
  return text + ")";
}

// Runs one runtime call; a synchronous SYCL error becomes a BackendError naming what was being done.
template <class F>
auto guarded(const char* what, F&& body) {
  try {
    return body();
  } catch (const sycl::exception& e) {
    throw BackendError(fmt::format("sycl: {} failed: {}", what, one_line(e.what())));
  }
}

// One USM device allocation, freed through the queue it was made on (which outlives it).
class DeviceMemory {
 public:
  explicit DeviceMemory(sycl::queue& queue) : queue_(queue) {}
  DeviceMemory(const DeviceMemory&) = delete;
  DeviceMemory& operator=(const DeviceMemory&) = delete;
  ~DeviceMemory() { release(); }

  void* allocate(std::size_t bytes, const char* what) {
    release();
    // Never zero bytes: a null pointer would be indistinguishable from a failed allocation.
    const std::size_t size = std::max<std::size_t>(bytes, 16);
    pointer_ = guarded(what, [&] { return sycl::malloc_device(size, queue_); });
    if (!pointer_) throw BackendError(fmt::format("sycl: {} failed: out of device memory ({} bytes)", what, size));
    return pointer_;
  }

  template <class V>
  const typename V::value_type* upload(const V& host, const char* what) {
    const std::size_t bytes = host.size() * sizeof(typename V::value_type);
    void* device = allocate(bytes, what);
    if (bytes > 0) guarded(what, [&] { queue_.memcpy(device, host.data(), bytes).wait_and_throw(); });
    return static_cast<const typename V::value_type*>(device);
  }

  void release() {
    if (pointer_) sycl::free(pointer_, queue_);
    pointer_ = nullptr;
  }

 private:
  sycl::queue& queue_;
  void* pointer_ = nullptr;
};

// Device storage of the wavefront's pools and queues, and each stage as one parallel_for over its queue. The
// host waits after each stage, which gives its time (wall clock) and is needed anyway to read the queue lengths.
template <class T>
class SyclWavefrontStages final : public WavefrontStages {
 public:
  SyclWavefrontStages(sycl::queue& queue, std::function<void(const char*)> synchronise, const SceneView<T>& scene,
                      FilmPixel* film, u32 pool_capacity)
      : WavefrontStages(scene.params.width * scene.params.height, pool_capacity), queue_(queue), synchronise_(std::move(synchronise)),
        scene_(scene), film_(film) {
    allocate_wavefront(*this, view_,
                       [&](std::size_t bytes) { return memory_.emplace_back(queue_).allocate(bytes, "allocating the wavefront path pool"); });
    guarded("clearing the wavefront queues", [&] { queue_.memset(view_.counters, 0, kWavefrontCounters * sizeof(u32)); });
    synchronise_("clearing the wavefront queues");
  }

  void begin_batch(u32 first_sample, u32) override { view_.first_sample = first_sample; }
  void generate(u32 first_slot, u32 count, u32 first_item) override {
    run(0, count, [=, scene = scene_, view = view_](u32 i) { wavefront_generate(scene, view, first_slot + i, first_item + i); });
  }
  void intersect(u32 count) override {
    run(1, count, [scene = scene_, view = view_](u32 i) { wavefront_intersect(scene, view, i); });
  }
  void escaped(u32 count) override {
    run(2, count, [scene = scene_, view = view_](u32 i) { wavefront_escaped(scene, view, i); });
  }
  void shade(u32 material_class, u32 count) override {
    run(3, count, [=, scene = scene_, view = view_](u32 i) { wavefront_shade(scene, view, material_class, i); });
  }
  void accumulate(u32 sample_count) override {
    run(4, view_.pixels, [=, view = view_, film = film_](u32 pixel) { wavefront_accumulate(view, film, pixel, sample_count); });
  }
  std::array<u32, kWavefrontCounters> take_counters() override {
    std::array<u32, kWavefrontCounters> values{};
    guarded("reading the wavefront queues", [&] {
      queue_.memcpy(values.data(), view_.counters, sizeof(values));
      queue_.memset(view_.counters, 0, sizeof(values));
    });
    synchronise_("reading the wavefront queues");
    return values;
  }
  void swap_pools() override { view_.swap_pools(); }

 private:
  template <class F>
  void run(int stage, u32 count, const F& body) {
    if (count == 0) return;
    const auto start = std::chrono::steady_clock::now();
    guarded("launching a wavefront stage", [&] {
      queue_.parallel_for(sycl::range<1>(count), [=](sycl::item<1> item) { body(static_cast<u32>(item.get_id(0))); });
    });
    synchronise_("running a wavefront stage");
    seconds_[stage] += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  sycl::queue& queue_;
  std::function<void(const char*)> synchronise_;
  SceneView<T> scene_;
  FilmPixel* film_;
  std::deque<DeviceMemory> memory_;  // declared after the queue reference, freed through it
  WavefrontView<T> view_{};
};

// A CPU device's runtime may hand each thread one contiguous block of rows, and image rows differ widely in cost
// (sky above, geometry below). Work item row r renders image row (r * stride) mod height: a stride near
// height / golden ratio and coprime with the height visits every row once and spreads each block over the image.
u32 spreading_stride(u32 height) {
  u32 stride = std::max<u32>(1, static_cast<u32>(height * 0.618));
  while (std::gcd(stride, height) != 1) ++stride;
  return stride;
}

sycl::device pick_device(int index) {
  if (index < 0) return guarded("choosing the default device", [] { return sycl::device(sycl::default_selector_v); });
  const std::vector<sycl::device> devices = guarded("listing the devices", [] { return sycl::device::get_devices(); });
  if (devices.empty()) throw BackendError("sycl: no device found");
  if (static_cast<std::size_t>(index) >= devices.size())
    throw BackendError(fmt::format("sycl: there is no device {} ({} found; see `pathtracer devices`)", index, devices.size()));
  return devices[static_cast<std::size_t>(index)];
}

template <class T>
class SyclBackend final : public RenderBackend<T> {
 public:
  SyclBackend(int device_index, Integrator integrator)
      : device_index_(device_index), integrator_(integrator), device_(pick_device(device_index)), queue_(make_queue()),
        description_(describe(device_)) {
    // The film sums samples in double whatever the scalar type, so a device without fp64 cannot run the kernel.
    if (!device_.has(sycl::aspect::fp64))
      throw BackendError(fmt::format("sycl: device {} ({}) has no double precision, which the film needs", device_index_,
                                     device_.get_info<sycl::info::device::name>()));
  }

  std::string name() const override {
    return fmt::format("sycl (device {}: {}, {})", device_index_ < 0 ? std::string("default") : std::to_string(device_index_),
                       description_, integrator_ == Integrator::kWavefront ? "wavefront" : "megakernel");
  }

  void upload(const FlatScene<T>& scene) override {
    wavefront_.reset();
    scene_memory_.clear();
    view_ = place_scene(scene, [&](const auto& array, const char* what) { return scene_memory_.emplace_back(queue_).upload(array, what); });
    pixels_ = static_cast<std::size_t>(scene.params.width) * scene.params.height;
    film_ = static_cast<FilmPixel*>(film_memory_.allocate(pixels_ * sizeof(FilmPixel), "allocating the film"));
    guarded("clearing the film", [&] { queue_.memset(film_, 0, pixels_ * sizeof(FilmPixel)); });
    synchronise("clearing the film");
    samples_per_batch_ = 1;
    row_stride_ = host_device_ ? spreading_stride(scene.params.height) : 1;
    if (integrator_ == Integrator::kWavefront) {
      // Pools as large as the CUDA backend's on a GPU, as the CPU backend's elsewhere (see BENCHMARKS.md).
      wavefront_ = std::make_unique<SyclWavefrontStages<T>>(queue_, [this](const char* what) { synchronise(what); }, view_, film_,
                                                            device_.is_gpu() ? kGpuWavefrontPool : kHostWavefrontPool);
    }
  }

  std::vector<std::pair<std::string, double>> stage_seconds() const override {
    return wavefront_ ? wavefront_->stage_seconds() : std::vector<std::pair<std::string, double>>{};
  }

  void render(u32 first_sample, u32 sample_count) override {
    if (wavefront_) {
      run_wavefront(*wavefront_, first_sample, sample_count);
      return;
    }
    const SceneView<T> view = view_;
    FilmPixel* const film = film_;
    const u32 width = view.params.width;
    const sycl::range<2> image(view.params.height, view.params.width);
    u32 done = 0;
    while (done < sample_count) {
      const u32 count = std::min(samples_per_batch_, sample_count - done);
      const auto start = std::chrono::steady_clock::now();
      // On a GPU, one sample per work item and launch, as in the CUDA backend (launches stay short). On a CPU
      // device a launch costs a fork and join of the worker threads, so a work item takes the batch's samples
      // of its pixel in order: the same sums in the same order either way, so the same image.
      const u32 per_launch = host_device_ ? count : 1;
      const u32 row_stride = row_stride_;
      for (u32 s = first_sample + done; s < first_sample + done + count; s += per_launch) {
        guarded("launching the render kernel", [&] {
          queue_.parallel_for(image, [=](sycl::item<2> item) {
            const u32 x = static_cast<u32>(item.get_id(1));
            const u32 y = static_cast<u32>((item.get_id(0) * row_stride) % view.params.height);
            accumulate_pixel(view, x, y, s, per_launch, film[static_cast<std::size_t>(y) * width + x]);
          });
        });
      }
      synchronise("running the render kernel");
      done += count;
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      samples_per_batch_ = next_batch_samples(seconds, count, kBatchTargetSeconds);
    }
  }

  void read_film(std::vector<FilmPixel>& pixels) override {
    pixels.resize(pixels_);
    guarded("reading the film back", [&] { queue_.memcpy(pixels.data(), film_, pixels_ * sizeof(FilmPixel)); });
    synchronise("reading the film back");
  }

 private:
  static constexpr double kBatchTargetSeconds = 0.1;

  // In order: every launch adds to the same film pixels, and USM carries no dependencies of its own.
  // Asynchronous errors are collected by the handler and thrown as one line at the next synchronisation.
  sycl::queue make_queue() {
    return guarded("creating a queue", [&] {
      return sycl::queue(device_, [this](sycl::exception_list errors) { collect(errors); },
                         sycl::property_list{sycl::property::queue::in_order()});
    });
  }

  void collect(const sycl::exception_list& errors) {
    for (const std::exception_ptr& error : errors) {
      try {
        std::rethrow_exception(error);
      } catch (const std::exception& e) {
        async_errors_.push_back(one_line(e.what()));
      } catch (...) {
        async_errors_.push_back("unknown error");
      }
    }
  }

  // Waits for everything queued; a synchronous or asynchronous error becomes one BackendError line.
  void synchronise(const char* what) {
    guarded(what, [&] { queue_.wait_and_throw(); });
    if (async_errors_.empty()) return;
    std::string message = async_errors_.front();
    if (async_errors_.size() > 1) message += fmt::format(" (and {} more)", async_errors_.size() - 1);
    async_errors_.clear();
    throw BackendError(fmt::format("sycl: {} failed: {}", what, message));
  }

  int device_index_;
  Integrator integrator_;
  sycl::device device_;
  bool host_device_ = device_.is_cpu();
  u32 row_stride_ = 1;
  std::vector<std::string> async_errors_;
  sycl::queue queue_;  // declared before the allocations, so it is destroyed after them
  std::string description_;
  std::deque<DeviceMemory> scene_memory_;  // one per scene array (deque: allocations do not move)
  DeviceMemory film_memory_{queue_};
  SceneView<T> view_{};
  FilmPixel* film_ = nullptr;
  std::size_t pixels_ = 0;
  u32 samples_per_batch_ = 1;
  std::unique_ptr<SyclWavefrontStages<T>> wavefront_;  // last: freed before the scene and film it points into
};

}  // namespace

template <class T>
std::unique_ptr<RenderBackend<T>> make_sycl_backend(int device, Integrator integrator) {
  return std::make_unique<SyclBackend<T>>(device, integrator);
}

template std::unique_ptr<RenderBackend<float>> make_sycl_backend<float>(int, Integrator);
template std::unique_ptr<RenderBackend<double>> make_sycl_backend<double>(int, Integrator);

void list_sycl_devices() {
  std::vector<sycl::device> devices;
  try {
    devices = sycl::device::get_devices();
  } catch (const sycl::exception& e) {
    fmt::print("sycl: no usable device ({})\n", one_line(e.what()));
    return;
  }
  if (devices.empty()) fmt::print("sycl: no device\n");
  for (std::size_t i = 0; i < devices.size(); ++i) fmt::print("sycl {}: {}\n", i, describe(devices[i]));
}

}  // namespace pt
