// The CUDA backend: the CUDA device (plain device allocations, launches on the default stream, CUDA events for
// timing) under the integrators written once in src/integrators. Compiled by nvcc, which instantiates the
// launches of the shared kernels; everything those kernels run is in src/kernel.
#include "backends/cuda/cuda_backend.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "backends/device_backend.hpp"
#include "base/scalar_types.hpp"

namespace pt {

// A named namespace, not an anonymous one: the Device concept's check names launches with probe kernels, and
// nvcc warns about member templates of internal linkage declared that way and never called.
namespace cuda_detail {

void check(cudaError_t status, const char* what) {
  if (status != cudaSuccess) {
    cudaGetLastError();  // clear a non-sticky error so that later calls report their own
    throw BackendError(std::string("cuda: ") + what + " failed: " + cudaGetErrorString(status));
  }
}

template <class Kernel>
__global__ void run_items(Kernel kernel, u32 count) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) kernel(i);
}

template <class Kernel>
__global__ void run_image(Kernel kernel, u32 width, u32 height) {
  const u32 x = blockIdx.x * blockDim.x + threadIdx.x;
  const u32 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x < width && y < height) kernel(x, y);
}

class CudaDevice {
 public:
  explicit CudaDevice(int index) : index_(index) {
    int count = 0;
    check(cudaGetDeviceCount(&count), "looking for GPUs");
    if (count == 0) throw BackendError("cuda: no GPU found");
    if (index < 0 || index >= count) throw BackendError("cuda: there is no GPU " + std::to_string(index) + " (" + std::to_string(count) + " found)");
    check(cudaSetDevice(index), "selecting the GPU");
    check(cudaGetDeviceProperties(&properties_, index), "reading the GPU's properties");
  }
  CudaDevice(const CudaDevice&) = delete;
  CudaDevice& operator=(const CudaDevice&) = delete;
  ~CudaDevice() {
    for (Timing& t : timings_) {
      cudaEventDestroy(t.start);
      cudaEventDestroy(t.stop);
    }
  }

  std::string kind() const { return "cuda"; }
  std::string description() const {
    return "GPU " + std::to_string(index_) + ": " + properties_.name + ", " + std::to_string(properties_.multiProcessorCount) + " SMs";
  }
  bool host() const { return false; }
  // What `auto` takes here: through nvcc the wavefront is the faster on the H200 (BENCHMARKS.md).
  Integrator preferred_integrator() const { return Integrator::kWavefront; }
  bool memory_on_host() const { return false; }
  bool times_on_device() const { return true; }

  void* allocate(std::size_t bytes, const char* what) {
    check(cudaSetDevice(index_), "selecting the GPU");
    void* pointer = nullptr;
    // Never zero bytes: every array gets an address of its own.
    check(cudaMalloc(&pointer, std::max<std::size_t>(bytes, 16)), what);
    return pointer;
  }
  void release(void* pointer) { cudaFree(pointer); }
  void copy_to_device(void* to, const void* from, std::size_t bytes, const char* what) {
    check(cudaMemcpy(to, from, bytes, cudaMemcpyHostToDevice), what);
  }
  void copy_to_host(void* to, const void* from, std::size_t bytes, const char* what) {
    check(cudaMemcpy(to, from, bytes, cudaMemcpyDeviceToHost), what);
    collect_timings();
  }
  void clear(void* to, std::size_t bytes, const char* what) { check(cudaMemsetAsync(to, 0, bytes), what); }
  void synchronise(const char* what) {
    check(cudaDeviceSynchronize(), what);
    collect_timings();
  }

  template <class Kernel>
  void launch(const char* what, u32 count, const Kernel& kernel) {
    if (count == 0) return;
    run_items<<<(count + kItemBlock - 1) / kItemBlock, kItemBlock>>>(kernel, count);
    check(cudaGetLastError(), what);
  }

  template <class Kernel>
  void launch_image(const char* what, u32 width, u32 height, const Kernel& kernel) {
    const dim3 block(kImageBlockWidth, kImageBlockHeight);
    const dim3 grid((width + block.x - 1) / block.x, (height + block.y - 1) / block.y);
    run_image<<<grid, block>>>(kernel, width, height);
    check(cudaGetLastError(), what);
  }

  // A timer is a pair of events around the launches; their time is read at the next synchronisation.
  using Timer = std::size_t;
  Timer start_timer() {
    if (pending_ == timings_.size()) {
      Timing t{};
      check(cudaEventCreate(&t.start), "creating an event");
      check(cudaEventCreate(&t.stop), "creating an event");
      timings_.push_back(t);
    }
    check(cudaEventRecord(timings_[pending_].start), "recording an event");
    timings_[pending_].seconds = nullptr;  // open until stopped
    return pending_++;
  }
  void stop_timer(Timer timer, double* seconds) {
    timings_[timer].seconds = seconds;
    check(cudaEventRecord(timings_[timer].stop), "recording an event");
  }

  u64 saturations() const { return 0; }

 private:
  static constexpr u32 kItemBlock = 128;
  static constexpr u32 kImageBlockWidth = 16, kImageBlockHeight = 8;

  struct Timing {
    cudaEvent_t start, stop;
    double* seconds;
  };

  void collect_timings() {
    for (std::size_t i = 0; i < pending_; ++i) {
      // An open timer's stop event is stale or unrecorded: a host wait inside a timed span is the caller's error.
      if (timings_[i].seconds == nullptr) throw std::logic_error("cuda: the host waited for the GPU inside a timed span of launches");
      check(cudaEventSynchronize(timings_[i].stop), "running a kernel");
      float milliseconds = 0;
      check(cudaEventElapsedTime(&milliseconds, timings_[i].start, timings_[i].stop), "timing a kernel");
      *timings_[i].seconds += milliseconds * 1e-3;
    }
    pending_ = 0;
  }

  int index_;
  cudaDeviceProp properties_{};
  std::vector<Timing> timings_;  // events are made once and reused
  std::size_t pending_ = 0;
};

static_assert(Device<CudaDevice>);

}  // namespace cuda_detail

template <class T>
std::unique_ptr<RenderBackend<T>> make_cuda_backend(int device, Integrator integrator) {
  return std::make_unique<DeviceBackend<cuda_detail::CudaDevice, T>>(integrator, device);
}

#define PT_INSTANTIATE_CUDA_BACKEND(...) template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_cuda_backend<__VA_ARGS__>(int, Integrator);
PT_FOR_EACH_FLOATING_TYPE(PT_INSTANTIATE_CUDA_BACKEND)

int cuda_device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();
    return 0;
  }
  return count;
}

std::vector<DeviceDescription> cuda_devices() {
  int count = 0;
  const cudaError_t status = cudaGetDeviceCount(&count);
  if (status != cudaSuccess) return {{"cuda", -1, std::string("no usable GPU (") + cudaGetErrorString(status) + ")"}};
  if (count == 0) return {{"cuda", -1, "no GPU"}};
  std::vector<DeviceDescription> devices;
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp p{};
    if (cudaGetDeviceProperties(&p, i) != cudaSuccess) continue;
    char text[512];
    std::snprintf(text, sizeof text, "%s (compute capability %d.%d, %d SMs, %.1f GiB)", p.name, p.major, p.minor, p.multiProcessorCount,
                  p.totalGlobalMem / 1073741824.0);
    devices.push_back({"cuda", i, text});
  }
  return devices;
}

}  // namespace pt
