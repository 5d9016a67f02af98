// The SYCL backend: the SYCL device (USM device allocations, an in-order queue, parallel_for launches, profiling
// events for timing) under the integrators written once in src/integrators. Compiled by a SYCL compiler only.

// The SYCL header comes first: the kernel headers choose their SYCL paths (atomics, no x86 builtins in code that
// may be compiled for a GPU) from whether it was seen, and sycl_backend.hpp already reaches them.
#include <sycl/sycl.hpp>

#include "backends/sycl/sycl_backend.hpp"

#if !defined(PT_SYCL_KERNELS)
#error "the kernel headers were reached before the SYCL header: they would take their CPU-only paths"
#endif

#include <algorithm>
#include <chrono>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "backends/device_backend.hpp"
#include "base/scalar_types.hpp"

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
  std::string text =
      fmt::format("{} ({}, {}; {} compute units", device.get_info<sycl::info::device::name>(), kind,
                  device.get_platform().get_info<sycl::info::platform::name>(), device.get_info<sycl::info::device::max_compute_units>());
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

class SyclDevice {
 public:
  explicit SyclDevice(int index)
      : index_(index),
        device_(pick_device(index)),
        host_(device_.is_cpu()),
        profiling_(device_.has(sycl::aspect::queue_profiling)),
        queue_(make_queue()),
        description_(describe(device_)) {
    // The film sums samples in double whatever the scalar type, so a device without fp64 cannot run the kernel.
    if (!device_.has(sycl::aspect::fp64))
      throw BackendError(
          fmt::format("sycl: device {} ({}) has no double precision, which the film needs", index_, device_.get_info<sycl::info::device::name>()));
  }
  SyclDevice(const SyclDevice&) = delete;
  SyclDevice& operator=(const SyclDevice&) = delete;

  std::string kind() const { return "sycl"; }
  std::string description() const { return fmt::format("device {}: {}", index_ < 0 ? std::string("default") : std::to_string(index_), description_); }
  bool host() const { return host_; }
  // What `auto` takes here: the megakernel, on the host and on GPUs alike. On the H200 through AdaptiveCpp the
  // megakernel was the faster on every benchmark scene (its wavefront's intersect stage runs 4x slower than nvcc's;
  // docs/backends.md).
  Integrator preferred_integrator() const { return Integrator::kMegakernel; }
  bool memory_on_host() const { return false; }  // device allocations, even on a CPU device
  bool times_on_device() const { return profiling_; }

  void* allocate(std::size_t bytes, const char* what) {
    // Never zero bytes: a null pointer would be indistinguishable from a failed allocation.
    const std::size_t size = std::max<std::size_t>(bytes, 16);
    void* pointer = guarded(what, [&] { return sycl::malloc_device(size, queue_); });
    if (!pointer) throw BackendError(fmt::format("sycl: {} failed: out of device memory ({} bytes)", what, size));
    return pointer;
  }
  void release(void* pointer) { sycl::free(pointer, queue_); }
  void copy_to_device(void* to, const void* from, std::size_t bytes, const char* what) {
    guarded(what, [&] { queue_.memcpy(to, from, bytes); });
  }
  void copy_to_host(void* to, const void* from, std::size_t bytes, const char* what) {
    guarded(what, [&] { queue_.memcpy(to, from, bytes); });
    synchronise(what);
  }
  void clear(void* to, std::size_t bytes, const char* what) {
    guarded(what, [&] { queue_.memset(to, 0, bytes); });
  }

  // Waits for everything queued; a synchronous or asynchronous error becomes one BackendError line.
  void synchronise(const char* what) {
    guarded(what, [&] { queue_.wait_and_throw(); });
    if (!async_errors_.empty()) {
      std::string message = async_errors_.front();
      if (async_errors_.size() > 1) message += fmt::format(" (and {} more)", async_errors_.size() - 1);
      async_errors_.clear();
      throw BackendError(fmt::format("sycl: {} failed: {}", what, message));
    }
    collect_timings(what);
  }

  template <class Kernel>
  void launch(const char* what, u32 count, const Kernel& kernel) {
    if (count == 0) return;
    record(guarded(what, [&] {
      if (host_) return queue_.parallel_for(sycl::range<1>(count), [=](sycl::item<1> item) { kernel(static_cast<u32>(item.get_id(0))); });
      // On a GPU, groups of the CUDA backend's size; the last group's extra items do nothing.
      const std::size_t groups = (count + kItemGroup - 1) / kItemGroup;
      return queue_.parallel_for(sycl::nd_range<1>(groups * kItemGroup, kItemGroup), [=](sycl::nd_item<1> item) {
        const u32 i = static_cast<u32>(item.get_global_id(0));
        if (i < count) kernel(i);
      });
    }));
  }

  template <class Kernel>
  void launch_image(const char* what, u32 width, u32 height, const Kernel& kernel) {
    record(guarded(what, [&] {
      if (host_) {
        const u32 stride = spreading_stride(height);
        return queue_.parallel_for(sycl::range<2>(height, width), [=](sycl::item<2> item) {
          kernel(static_cast<u32>(item.get_id(1)), static_cast<u32>((item.get_id(0) * stride) % height));
        });
      }
      // On a GPU, 16x8 pixel groups as in the CUDA backend.
      const sycl::range<2> group(kImageGroupHeight, kImageGroupWidth);
      const sycl::range<2> global((height + kImageGroupHeight - 1) / kImageGroupHeight * kImageGroupHeight,
                                  (width + kImageGroupWidth - 1) / kImageGroupWidth * kImageGroupWidth);
      return queue_.parallel_for(sycl::nd_range<2>(global, group), [=](sycl::nd_item<2> item) {
        const u32 x = static_cast<u32>(item.get_global_id(1)), y = static_cast<u32>(item.get_global_id(0));
        if (x < width && y < height) kernel(x, y);
      });
    }));
  }

  // With profiling, a timer spans the device time from the start of the first launch after start_timer() to the
  // end of the last before stop_timer(), read at the next synchronisation; without, the host waits and reads
  // its wall clock.
  struct Timer {
    std::size_t first_launch;
    std::chrono::steady_clock::time_point start;
  };
  Timer start_timer() {
    if (!profiling_) guarded("running a kernel", [&] { queue_.wait_and_throw(); });
    return Timer{launched_.size(), std::chrono::steady_clock::now()};
  }
  void stop_timer(Timer timer, double* seconds) {
    if (!profiling_) {
      synchronise("running a kernel");
      *seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - timer.start).count();
      return;
    }
    if (launched_.size() > timer.first_launch) timings_.push_back(Timing{timer.first_launch, launched_.size() - 1, seconds});
  }

  u64 saturations() const { return 0; }

 private:
  static constexpr std::size_t kItemGroup = 128;
  static constexpr std::size_t kImageGroupWidth = 16, kImageGroupHeight = 8;

  struct Timing {
    std::size_t first, last;  // indices into launched_
    double* seconds;
  };

  void record(const sycl::event& event) {
    if (profiling_) launched_.push_back(event);
  }

  void collect_timings(const char* what) {
    guarded(what, [&] {
      for (const Timing& t : timings_) {
        const auto start = launched_[t.first].get_profiling_info<sycl::info::event_profiling::command_start>();
        const auto end = launched_[t.last].get_profiling_info<sycl::info::event_profiling::command_end>();
        *t.seconds += static_cast<double>(end - start) * 1e-9;
      }
    });
    timings_.clear();
    launched_.clear();
  }

  // In order: every launch adds to the same film pixels, and USM carries no dependencies of its own.
  // Asynchronous errors are collected by the handler and thrown as one line at the next synchronisation.
  sycl::queue make_queue() {
    return guarded("creating a queue", [&] {
      sycl::property_list properties = profiling_ ? sycl::property_list{sycl::property::queue::in_order(), sycl::property::queue::enable_profiling()}
                                                  : sycl::property_list{sycl::property::queue::in_order()};
      return sycl::queue(
          device_, [this](sycl::exception_list errors) { collect(errors); }, properties);
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

  int index_;
  sycl::device device_;
  bool host_;
  bool profiling_;
  std::vector<std::string> async_errors_;
  sycl::queue queue_;
  std::string description_;
  std::vector<sycl::event> launched_;  // since the last synchronisation, with profiling
  std::vector<Timing> timings_;
};

static_assert(Device<SyclDevice>);

}  // namespace

template <class T>
std::unique_ptr<RenderBackend<T>> make_sycl_backend(int device, Integrator integrator) {
  return std::make_unique<DeviceBackend<SyclDevice, T>>(integrator, device);
}

#define PT_INSTANTIATE_SYCL_BACKEND(...) template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_sycl_backend<__VA_ARGS__>(int, Integrator);
PT_FOR_EACH_FLOATING_TYPE(PT_INSTANTIATE_SYCL_BACKEND)

std::vector<DeviceDescription> sycl_devices() {
  std::vector<sycl::device> devices;
  try {
    devices = sycl::device::get_devices();
  } catch (const sycl::exception& e) {
    return {{"sycl", -1, fmt::format("no usable device ({})", one_line(e.what()))}};
  }
  if (devices.empty()) return {{"sycl", -1, "no device"}};
  std::vector<DeviceDescription> described;
  for (std::size_t i = 0; i < devices.size(); ++i) described.push_back({"sycl", static_cast<int>(i), describe(devices[i])});
  return described;
}

}  // namespace pt
