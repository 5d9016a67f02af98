// The CUDA entry points: each thread runs the shared kernel code (accumulate_pixel) for one pixel. Only this file
// is compiled by nvcc; everything it runs is in src/kernel.
#include "backends/cuda/cuda_kernels.hpp"

namespace pt {

namespace {

// One sample of one pixel per thread. A thread never loops over several samples: with such a loop, samples
// after the first in a thread came out non-finite at a rate near 1e-5 on sm_90 (never the first, never on the
// CPU, and not under compute-sanitizer), so every launch starts its warps converged on a fresh sample.
template <class T>
__global__ void render_sample(SceneView<T> scene, FilmPixel* film, u32 sample) {
  const u32 x = blockIdx.x * blockDim.x + threadIdx.x;
  const u32 y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= scene.params.width || y >= scene.params.height) return;
  accumulate_pixel(scene, x, y, sample, 1, film[static_cast<size_t>(y) * scene.params.width + x]);
}

constexpr u32 kStageBlock = 128;

template <class T>
__global__ void wavefront_generate_kernel(SceneView<T> scene, WavefrontView<T> w, u32 count, u32 first_slot, u32 first_item) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) wavefront_generate(scene, w, first_slot + i, first_item + i);
}

template <class T>
__global__ void wavefront_intersect_kernel(SceneView<T> scene, WavefrontView<T> w, u32 count) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) wavefront_intersect(scene, w, i);
}

template <class T>
__global__ void wavefront_escaped_kernel(SceneView<T> scene, WavefrontView<T> w, u32 count) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) wavefront_escaped(scene, w, i);
}

template <class T>
__global__ void wavefront_shade_kernel(SceneView<T> scene, WavefrontView<T> w, u32 count, u32 material_class) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) wavefront_shade(scene, w, material_class, i);
}

template <class T>
__global__ void wavefront_accumulate_kernel(WavefrontView<T> w, FilmPixel* film, u32 count, u32 sample_count) {
  const u32 i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < count) wavefront_accumulate(w, film, i, sample_count);
}

}  // namespace

template <class T>
cudaError_t launch_wavefront_stage(WavefrontStage stage, u32 count, const SceneView<T>& scene, const WavefrontView<T>& w,
                                   FilmPixel* film, u32 a, u32 b) {
  if (count == 0) return cudaSuccess;
  const dim3 grid((count + kStageBlock - 1) / kStageBlock), block(kStageBlock);
  switch (stage) {
    case WavefrontStage::kGenerate: wavefront_generate_kernel<T><<<grid, block>>>(scene, w, count, a, b); break;
    case WavefrontStage::kIntersect: wavefront_intersect_kernel<T><<<grid, block>>>(scene, w, count); break;
    case WavefrontStage::kEscaped: wavefront_escaped_kernel<T><<<grid, block>>>(scene, w, count); break;
    case WavefrontStage::kShade: wavefront_shade_kernel<T><<<grid, block>>>(scene, w, count, a); break;
    case WavefrontStage::kAccumulate: wavefront_accumulate_kernel<T><<<grid, block>>>(w, film, count, a); break;
  }
  return cudaGetLastError();
}

template cudaError_t launch_wavefront_stage<float>(WavefrontStage, u32, const SceneView<float>&, const WavefrontView<float>&, FilmPixel*, u32, u32);
template cudaError_t launch_wavefront_stage<double>(WavefrontStage, u32, const SceneView<double>&, const WavefrontView<double>&, FilmPixel*, u32, u32);

template <class T>
cudaError_t launch_render_samples(dim3 grid, dim3 block, const SceneView<T>& scene, FilmPixel* film, u32 first_sample, u32 sample_count) {
  for (u32 s = first_sample; s < first_sample + sample_count; ++s) {
    render_sample<T><<<grid, block>>>(scene, film, s);
    if (const cudaError_t status = cudaGetLastError(); status != cudaSuccess) return status;
  }
  return cudaSuccess;
}

template cudaError_t launch_render_samples<float>(dim3, dim3, const SceneView<float>&, FilmPixel*, u32, u32);
template cudaError_t launch_render_samples<double>(dim3, dim3, const SceneView<double>&, FilmPixel*, u32, u32);

}  // namespace pt
