// The CUDA entry points: each thread runs the shared kernel code (accumulate_pixel) for one pixel. Only this file
// is compiled by nvcc; everything it runs is in src/kernel.
#include "backends/cuda/cuda_kernels.hpp"

namespace pt {

namespace {

template <class T>
__global__ void render_samples(SceneView<T> scene, FilmPixel* film, u32 first_sample, u32 sample_count) {
  const u32 x = blockIdx.x * blockDim.x + threadIdx.x;
  const u32 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= scene.params.width || y >= scene.params.height) return;
  accumulate_pixel(scene, x, y, first_sample, sample_count, film[static_cast<size_t>(y) * scene.params.width + x]);
}

}  // namespace

template <class T>
cudaError_t launch_render_samples(dim3 grid, dim3 block, const SceneView<T>& scene, FilmPixel* film, u32 first_sample, u32 sample_count) {
  render_samples<T><<<grid, block>>>(scene, film, first_sample, sample_count);
  return cudaGetLastError();
}

template cudaError_t launch_render_samples<float>(dim3, dim3, const SceneView<float>&, FilmPixel*, u32, u32);
template cudaError_t launch_render_samples<double>(dim3, dim3, const SceneView<double>&, FilmPixel*, u32, u32);

}  // namespace pt
