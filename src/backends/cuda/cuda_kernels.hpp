// Launchers of the CUDA kernels, callable from host code compiled by the host compiler.
#pragma once

#include <cuda_runtime.h>

#include "kernel/integrator.hpp"

namespace pt {

// Adds samples [first_sample, first_sample + sample_count) of every pixel to the device film, one launch per
// sample. Asynchronous; returns the first launch error.
template <class T>
cudaError_t launch_render_samples(dim3 grid, dim3 block, const SceneView<T>& scene, FilmPixel* film, u32 first_sample, u32 sample_count);

}  // namespace pt
