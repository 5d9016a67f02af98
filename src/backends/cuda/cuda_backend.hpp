// The CUDA backend: the same kernel headers compiled by nvcc, with the scene in plain device allocations.
#pragma once

#include <memory>
#include <vector>

#include "backends/backend.hpp"

namespace pt {

// Throws BackendError when no usable GPU is there.
template <class T>
std::unique_ptr<RenderBackend<T>> make_cuda_backend(int device, Integrator integrator = Integrator::kMegakernel);

// Number of usable CUDA devices (0 when the driver is missing or unusable).
int cuda_device_count();

// The CUDA devices, or why there are none.
std::vector<DeviceDescription> cuda_devices();

}  // namespace pt
