// The SYCL 2020 backend: the same kernel headers compiled by a SYCL compiler (AdaptiveCpp or DPC++), with the
// scene in USM device allocations. This header is plain C++, so host code built by any compiler can include it.
#pragma once

#include <memory>

#include "backends/backend.hpp"

namespace pt {

// `device` indexes sycl::device::get_devices() (as listed by list_sycl_devices); a negative index lets the
// runtime's default selector choose. Throws BackendError when the device is missing or unusable.
template <class T>
std::unique_ptr<RenderBackend<T>> make_sycl_backend(int device, Integrator integrator = Integrator::kMegakernel);

// Prints the SYCL devices, one a line with its index, to stdout.
void list_sycl_devices();

}  // namespace pt
