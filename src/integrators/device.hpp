// The few operations the integrators need from a device: memory, copies, kernel launches over items or over an
// image, synchronisation and timing. Each backend (CPU threads, CUDA, SYCL) provides them in a class of its own,
// and the integrators (megakernel.hpp, wavefront.hpp) are written once over them.
#pragma once

#include <concepts>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "base/errors.hpp"
#include "integrators/integrator_choice.hpp"
#include "kernel/platform.hpp"

namespace pt {

namespace device_detail {
struct ItemsKernelProbe {
  PT_HD void operator()(u32) const {}
};
struct ImageKernelProbe {
  PT_HD void operator()(u32, u32) const {}
};
}  // namespace device_detail

// What a device class offers. Errors of any operation throw BackendError with one line naming `what`.
//  - kind(), description(): "cuda" and "GPU 0: NVIDIA H200, 132 SMs", for the backend's name.
//  - host(): the device is the host's processor (a launch costs a fork and join of threads, so the megakernel
//    gives each work item many samples, and the wavefront keeps a pool that fits the caches).
//  - preferred_integrator(): what `--integrator auto` takes on it, the faster one as measured (BENCHMARKS.md).
//  - memory_on_host(): its allocations are host memory the program may read directly (no copy back needed); the
//    kernels then read the flat scene's host arrays themselves (DeviceBackend::upload makes no copy).
//  - times_on_device(): the timers read the device's own clock (events), not the host's wall clock.
//  - allocate(bytes, what) / release(pointer): device memory, aligned for any kernel struct.
//  - copy_to_device, clear: ordered after the work queued before; the source must stay alive until the next
//    synchronise(). copy_to_host returns once the data is on the host, after everything queued before it.
//  - launch(what, count, kernel): kernel(i) for every i in [0, count), asynchronously.
//  - launch_image(what, width, height, kernel): kernel(x, y) for every pixel, asynchronously, in whatever order
//    and grouping suits the device (tiles on a CPU, 2-D blocks on a GPU).
//  - start_timer() / stop_timer(timer, &seconds): adds the time of the work queued in between to `seconds`, at
//    the latest by the next synchronise() or copy_to_host(); neither may come between the two (the device reads
//    its timers there).
//  - saturations(): fixed-point saturations counted in kernels so far (0 where kernels do not count them).
template <class D>
concept Device = requires(D& device, const D& view, void* pointer, const void* source, std::size_t bytes, const char* what, u32 count,
                          double* seconds, typename D::Timer timer) {
  { view.kind() } -> std::convertible_to<std::string>;
  { view.description() } -> std::convertible_to<std::string>;
  { view.host() } -> std::convertible_to<bool>;
  { view.preferred_integrator() } -> std::same_as<Integrator>;
  { view.memory_on_host() } -> std::convertible_to<bool>;
  { view.times_on_device() } -> std::convertible_to<bool>;
  { device.allocate(bytes, what) } -> std::same_as<void*>;
  device.release(pointer);
  device.copy_to_device(pointer, source, bytes, what);
  device.copy_to_host(pointer, source, bytes, what);
  device.clear(pointer, bytes, what);
  device.launch(what, count, device_detail::ItemsKernelProbe{});
  device.launch_image(what, count, count, device_detail::ImageKernelProbe{});
  device.synchronise(what);
  { device.start_timer() } -> std::same_as<typename D::Timer>;
  device.stop_timer(timer, seconds);
  { view.saturations() } -> std::convertible_to<u64>;
};

// Device allocations owned together, released when replaced or destroyed (before the device itself goes).
template <Device D>
class DeviceAllocations {
 public:
  explicit DeviceAllocations(D& device) : device_(device) {}
  DeviceAllocations(const DeviceAllocations&) = delete;
  DeviceAllocations& operator=(const DeviceAllocations&) = delete;
  ~DeviceAllocations() { release_all(); }

  void* allocate(std::size_t bytes, const char* what) {
    pointers_.reserve(pointers_.size() + 1);  // so that the push below cannot throw and leak the allocation
    void* pointer = device_.allocate(bytes, what);
    pointers_.push_back(pointer);
    return pointer;
  }

  // A device copy of a host array.
  template <class V>
  const typename V::value_type* upload(const V& host, const char* what) {
    const std::size_t bytes = host.size() * sizeof(typename V::value_type);
    void* pointer = allocate(bytes, what);
    if (bytes > 0) device_.copy_to_device(pointer, host.data(), bytes, what);
    return static_cast<const typename V::value_type*>(pointer);
  }

  void release_all() {
    for (void* pointer : pointers_) device_.release(pointer);
    pointers_.clear();
  }

 private:
  D& device_;
  std::vector<void*> pointers_;
};

}  // namespace pt
