// Launchers of the CUDA kernels, callable from host code compiled by the host compiler.
#pragma once

#include <cuda_runtime.h>

#include "kernel/wavefront.hpp"

namespace pt {

// Adds samples [first_sample, first_sample + sample_count) of every pixel to the device film, one launch per
// sample. Asynchronous; returns the first launch error.
template <class T>
cudaError_t launch_render_samples(dim3 grid, dim3 block, const SceneView<T>& scene, FilmPixel* film, u32 first_sample, u32 sample_count);

enum class WavefrontStage { kGenerate, kIntersect, kEscaped, kShade, kAccumulate };

// Launches one wavefront stage over `count` queue entries (pixels for kAccumulate). `a` and `b` are the stage's
// arguments: generate (first slot, first item), shade (material class), accumulate (samples in the batch).
template <class T>
cudaError_t launch_wavefront_stage(WavefrontStage stage, u32 count, const SceneView<T>& scene, const WavefrontView<T>& view,
                                   FilmPixel* film, u32 a, u32 b);

}  // namespace pt
