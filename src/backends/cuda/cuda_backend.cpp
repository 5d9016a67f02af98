// The CUDA backend: a thin host layer that copies the flat scene into plain device allocations and launches the
// shared kernel (accumulate_pixel, through cuda_kernels.cu) over the image, in launches of bounded length.
#include "backends/cuda/cuda_backend.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>

#include <fmt/format.h>

#include "backends/cuda/cuda_kernels.hpp"

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

template <class T>
class CudaBackend final : public RenderBackend<T> {
 public:
  explicit CudaBackend(int device) : device_(device) {
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

  std::string name() const override { return fmt::format("cuda (GPU {}: {}, {} SMs)", device_, properties_.name, properties_.multiProcessorCount); }

  void upload(const FlatScene<T>& scene) override {
    check(cudaSetDevice(device_), "selecting the GPU");
    view_ = SceneView<T>{nodes_.upload(scene.nodes, "copying the BVH"),
                         primitives_.upload(scene.primitives, "copying the primitives"),
                         boundaries_.upload(scene.boundaries, "copying the medium boundaries"),
                         attributes_.upload(scene.triangle_attributes, "copying the triangle attributes"),
                         materials_.upload(scene.materials, "copying the materials"),
                         textures_.upload(scene.textures, "copying the textures"),
                         TextureData<T>{texels_.upload(scene.texels, "copying the texels"),
                                        gradients_.upload(scene.perlin_gradients, "copying the noise tables"),
                                        permutations_.upload(scene.perlin_permutations, "copying the noise tables")},
                         scene.camera,
                         scene.background,
                         scene.params};
    pixels_ = static_cast<size_t>(scene.params.width) * scene.params.height;
    film_ = static_cast<FilmPixel*>(film_buffer_.allocate(pixels_ * sizeof(FilmPixel), "allocating the film"));
    check(cudaMemset(film_, 0, pixels_ * sizeof(FilmPixel)), "clearing the film");
    samples_per_batch_ = 1;
    device_seconds_ = 0;
  }

  void render(u32 first_sample, u32 sample_count) override {
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
      // Synchronise about every kBatchTargetMs: often enough for progress and error reports; each launch inside a
      // batch is one sample, far below any display watchdog's limit.
      const double per_sample = milliseconds / count;
      const double wanted = per_sample > 0 ? kBatchTargetMs / per_sample : 2.0 * count;
      samples_per_batch_ = static_cast<u32>(std::clamp(wanted, 1.0, 2.0 * count + 1));
    }
  }

  void read_film(std::vector<FilmPixel>& pixels) override {
    pixels.resize(pixels_);
    check(cudaMemcpy(pixels.data(), film_, pixels_ * sizeof(FilmPixel), cudaMemcpyDeviceToHost), "reading the film back");
  }

  std::optional<double> device_seconds() const override { return device_seconds_; }

 private:
  static constexpr u32 kBlockWidth = 16, kBlockHeight = 8;
  static constexpr double kBatchTargetMs = 100.0;

  int device_;
  cudaDeviceProp properties_{};
  cudaEvent_t start_ = nullptr, stop_ = nullptr;
  DeviceBuffer nodes_, primitives_, boundaries_, attributes_, materials_, textures_, texels_, gradients_, permutations_, film_buffer_;
  SceneView<T> view_{};
  FilmPixel* film_ = nullptr;
  size_t pixels_ = 0;
  u32 samples_per_batch_ = 1;
  double device_seconds_ = 0;
};

}  // namespace

template <class T>
std::unique_ptr<RenderBackend<T>> make_cuda_backend(int device) {
  return std::make_unique<CudaBackend<T>>(device);
}

template std::unique_ptr<RenderBackend<float>> make_cuda_backend<float>(int);
template std::unique_ptr<RenderBackend<double>> make_cuda_backend<double>(int);

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
