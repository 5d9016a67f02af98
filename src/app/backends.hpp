// Which backends this build has, and making one by name.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/backend.hpp"

namespace pt {

std::vector<std::string> backend_names();
std::string backend_choices();

// "cpu", "cuda", "sycl" or "auto" (the CUDA GPU when one is usable, else the CPU; says which on stderr).
// `device` is the CUDA GPU; `sycl_device` indexes the SYCL devices (negative: the runtime's default choice).
template <class T>
std::unique_ptr<RenderBackend<T>> make_backend(const std::string& name, unsigned threads, int device,
                                               Integrator integrator = Integrator::kMegakernel, int sycl_device = -1);

// Prints every backend's devices to stdout.
void list_devices();

}  // namespace pt
