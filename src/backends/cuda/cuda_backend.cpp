// The CUDA backend: a thin host layer that copies the flat scene into plain device allocations and launches the
// shared kernels (through cuda_kernels.cu): the megakernel over the image, one sample per launch, or the
// wavefront stages over their queues.
#include "backends/cuda/cuda_backend.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <deque>
#include <cstdio>

#include <fmt/format.h>

#include "backends/cuda/cuda_kernels.hpp"
#include "backends/wavefront_schedule.hpp"

namespace pt {

namespace {

void check(cudaError_t status, const char* what) {
  if (status != cudaSuccess) {
    cudaGetLastError();  // clear a sticky-free error so later calls report their own
    throw BackendError(fmt::format("cuda: {} failed: {}", what, cudaGetErrorString(status)));
  }
}

// One device allocation holding a copy of a host vector.
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() { release(); }

  template <class V>
  const typename V::value_type* upload(const V& host, const char* what) {
    release();
    const size_t bytes = std::max<size_t>(host.size() * sizeof(typename V::value_type), 16);
    check(cudaMalloc(&pointer_, bytes), what);
    if (!host.empty()) check(cudaMemcpy(pointer_, host.data(), host.size() * sizeof(typename V::value_type), cudaMemcpyHostToDevice), what);
    return static_cast<const typename V::value_type*>(pointer_);
  }
  void* allocate(size_t bytes, const char* what) {
    release();
    check(cudaMalloc(&pointer_, std::max<size_t>(bytes, 16)), what);
    return pointer_;
  }
  void release() {
    if (pointer_) cudaFree(pointer_);
    pointer_ = nullptr;
  }

 private:
  void* pointer_ = nullptr;
};

// Device storage of the wavefront's pools and queues, and the stages as launches timed with CUDA events.
template <class T>
class CudaWavefrontStages final : public WavefrontStages {
 public:
  CudaWavefrontStages(const SceneView<T>& scene, FilmPixel* film)
      : WavefrontStages(scene.params.width * scene.params.height, kGpuWavefrontPool), scene_(scene), film_(film) {
    allocate_wavefront(*this, view_, [&](std::size_t bytes) {
      void* p = nullptr;
      check(cudaMalloc(&p, std::max<std::size_t>(bytes, 16)), "allocating the wavefront path pool");
      allocations_.push_back(p);
      return p;
    });
    check(cudaMemset(view_.counters, 0, kWavefrontCounters * sizeof(u32)), "clearing the wavefront queues");
  }
  ~CudaWavefrontStages() override {
    for (void* p : allocations_) cudaFree(p);
    for (Timing& t : timings_) {
      cudaEventDestroy(t.start);
      cudaEventDestroy(t.stop);
    }
  }

  void begin_batch(u32 first_sample, u32) override { view_.first_sample = first_sample; }
  void generate(u32 first_slot, u32 count, u32 first_item) override { run(WavefrontStage::kGenerate, 0, count, first_slot, first_item); }
  void intersect(u32 count) override { run(WavefrontStage::kIntersect, 1, count, 0, 0); }
  void escaped(u32 count) override { run(WavefrontStage::kEscaped, 2, count, 0, 0); }
  void shade(u32 material_class, u32 count) override { run(WavefrontStage::kShade, 3, count, material_class, 0); }
  void accumulate(u32 sample_count) override {
    run(WavefrontStage::kAccumulate, 4, view_.pixels, sample_count, 0);
    collect_timings();
  }
  std::array<u32, kWavefrontCounters> take_counters() override {
    std::array<u32, kWavefrontCounters> values{};
    check(cudaMemcpy(values.data(), view_.counters, sizeof(values), cudaMemcpyDeviceToHost), "reading the wavefront queues");
    check(cudaMemset(view_.counters, 0, sizeof(values)), "clearing the wavefront queues");
    collect_timings();
    return values;
  }
  void swap_pools() override { view_.swap_pools(); }

 private:
  // Launches are queued without waiting; their events are read at the next synchronisation (take_counters).
  void run(WavefrontStage stage, int timer, u32 count, u32 a, u32 b) {
    if (count == 0) return;
    if (pending_ == timings_.size()) {
      Timing t{};
      check(cudaEventCreate(&t.start), "creating an event");
      check(cudaEventCreate(&t.stop), "creating an event");
      timings_.push_back(t);
    }
    Timing& t = timings_[pending_++];
    t.timer = timer;
    check(cudaEventRecord(t.start), "recording an event");
    check(launch_wavefront_stage(stage, count, scene_, view_, film_, a, b), "launching a wavefront stage");
    check(cudaEventRecord(t.stop), "recording an event");
  }
  void collect_timings() {
    for (size_t i = 0; i < pending_; ++i) {
      check(cudaEventSynchronize(timings_[i].stop), "running a wavefront stage");
      float milliseconds = 0;
      check(cudaEventElapsedTime(&milliseconds, timings_[i].start, timings_[i].stop), "timing a wavefront stage");
      seconds_[timings_[i].timer] += milliseconds * 1e-3;
    }
    pending_ = 0;
  }

  struct Timing {
    cudaEvent_t start, stop;
    int timer;
  };

  const SceneView<T>& scene_;
  FilmPixel* film_;
  WavefrontView<T> view_{};
  std::vector<void*> allocations_;
  std::vector<Timing> timings_;
  size_t pending_ = 0;
};

template <class T>
class CudaBackend final : public RenderBackend<T> {
 public:
  CudaBackend(int device, Integrator integrator) : device_(device), integrator_(integrator) {
    int count = 0;
    check(cudaGetDeviceCount(&count), "looking for GPUs");
    if (count == 0) throw BackendError("cuda: no GPU found");
    if (device < 0 || device >= count) throw BackendError(fmt::format("cuda: there is no GPU {} ({} found)", device, count));
    check(cudaSetDevice(device), "selecting the GPU");
    check(cudaGetDeviceProperties(&properties_, device), "reading the GPU's properties");
    check(cudaEventCreate(&start_), "creating an event");
    check(cudaEventCreate(&stop_), "creating an event");
  }
  ~CudaBackend() override {
    cudaEventDestroy(start_);
    cudaEventDestroy(stop_);
  }

  std::string name() const override {
    return fmt::format("cuda (GPU {}: {}, {} SMs, {})", device_, properties_.name, properties_.multiProcessorCount,
                       integrator_ == Integrator::kWavefront ? "wavefront" : "megakernel");
  }

  std::vector<std::pair<std::string, double>> stage_seconds() const override {
    return wavefront_ ? wavefront_->stage_seconds() : std::vector<std::pair<std::string, double>>{};
  }

  void upload(const FlatScene<T>& scene) override {
    check(cudaSetDevice(device_), "selecting the GPU");
    scene_buffers_.clear();
    view_ = place_scene(scene, [&](const auto& array, const char* what) { return scene_buffers_.emplace_back().upload(array, what); });
    pixels_ = static_cast<size_t>(scene.params.width) * scene.params.height;
    film_ = static_cast<FilmPixel*>(film_buffer_.allocate(pixels_ * sizeof(FilmPixel), "allocating the film"));
    check(cudaMemset(film_, 0, pixels_ * sizeof(FilmPixel)), "clearing the film");
    samples_per_batch_ = 1;
    device_seconds_ = 0;
    wavefront_.reset();
    if (integrator_ == Integrator::kWavefront) {
      wavefront_ = std::make_unique<CudaWavefrontStages<T>>(view_, film_);
    }
  }

  void render(u32 first_sample, u32 sample_count) override {
    if (wavefront_) {
      run_wavefront(*wavefront_, first_sample, sample_count);
      device_seconds_ = wavefront_->total_seconds();
      return;
    }
    const dim3 block(kBlockWidth, kBlockHeight);
    const dim3 grid((view_.params.width + block.x - 1) / block.x, (view_.params.height + block.y - 1) / block.y);
    u32 done = 0;
    while (done < sample_count) {
      const u32 count = std::min(samples_per_batch_, sample_count - done);
      check(cudaEventRecord(start_), "recording an event");
      check(launch_render_samples(grid, block, view_, film_, first_sample + done, count), "launching the render kernel");
      check(cudaEventRecord(stop_), "recording an event");
      check(cudaEventSynchronize(stop_), "running the render kernel");
      float milliseconds = 0;
      check(cudaEventElapsedTime(&milliseconds, start_, stop_), "timing the render kernel");
      device_seconds_ += milliseconds * 1e-3;
      done += count;
      // Each launch inside a batch is one sample, far below any display watchdog's limit.
      samples_per_batch_ = next_batch_samples(milliseconds * 1e-3, count, kBatchTargetSeconds);
    }
  }

  void read_film(std::vector<FilmPixel>& pixels) override {
    pixels.resize(pixels_);
    check(cudaMemcpy(pixels.data(), film_, pixels_ * sizeof(FilmPixel), cudaMemcpyDeviceToHost), "reading the film back");
  }

  std::optional<double> device_seconds() const override { return device_seconds_; }

 private:
  static constexpr u32 kBlockWidth = 16, kBlockHeight = 8;
  static constexpr double kBatchTargetSeconds = 0.1;

  int device_;
  Integrator integrator_;
  std::unique_ptr<CudaWavefrontStages<T>> wavefront_;
  cudaDeviceProp properties_{};
  cudaEvent_t start_ = nullptr, stop_ = nullptr;
  std::deque<DeviceBuffer> scene_buffers_;  // one per scene array (deque: buffers do not move)
  DeviceBuffer film_buffer_;
  SceneView<T> view_{};
  FilmPixel* film_ = nullptr;
  size_t pixels_ = 0;
  u32 samples_per_batch_ = 1;
  double device_seconds_ = 0;
};

}  // namespace

template <class T>
std::unique_ptr<RenderBackend<T>> make_cuda_backend(int device, Integrator integrator) {
  return std::make_unique<CudaBackend<T>>(device, integrator);
}

template std::unique_ptr<RenderBackend<float>> make_cuda_backend<float>(int, Integrator);
template std::unique_ptr<RenderBackend<double>> make_cuda_backend<double>(int, Integrator);

int cuda_device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();
    return 0;
  }
  return count;
}

void list_cuda_devices() {
  int count = 0;
  const cudaError_t status = cudaGetDeviceCount(&count);
  if (status != cudaSuccess) {
    fmt::print("cuda: no usable GPU ({})\n", cudaGetErrorString(status));
    return;
  }
  if (count == 0) fmt::print("cuda: no GPU\n");
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp p{};
    if (cudaGetDeviceProperties(&p, i) != cudaSuccess) continue;
    fmt::print("cuda {}: {} (compute capability {}.{}, {} SMs, {:.1f} GiB)\n", i, p.name, p.major, p.minor, p.multiProcessorCount,
               p.totalGlobalMem / 1073741824.0);
  }
}

}  // namespace pt
