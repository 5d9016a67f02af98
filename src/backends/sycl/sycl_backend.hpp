// The SYCL 2020 backend: the same kernel headers compiled by a SYCL compiler (AdaptiveCpp or DPC++), with the
// scene in USM device allocations. This header is plain C++, so host code built by any compiler can include it.
#pragma once

#include <memory>
#include <vector>

#include "backends/backend.hpp"

namespace pt {

// `device` indexes sycl::device::get_devices() (as sycl_devices lists them); a negative index lets the
// runtime's default selector choose. Throws BackendError when the device is missing or unusable.
template <class T>
std::unique_ptr<RenderBackend<T>> make_sycl_backend(int device, Integrator integrator = Integrator::kMegakernel);

// The SYCL devices, by the index --sycl-device takes, or why there are none.
std::vector<DeviceDescription> sycl_devices();

}  // namespace pt
