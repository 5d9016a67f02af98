// The CPU backend: the integrators over the CPU device. Included by one source file per group of scalar types.
#pragma once

#include <memory>

#include "backends/cpu/cpu_backend.hpp"
#include "backends/cpu/cpu_device.hpp"
#include "backends/device_backend.hpp"
#include "base/scalar_types.hpp"

namespace pt {

template <class T>
std::unique_ptr<RenderBackend<T>> make_cpu_backend(unsigned threads, Integrator integrator) {
  return std::make_unique<DeviceBackend<CpuDevice, T>>(integrator, threads);
}

#define PT_INSTANTIATE_CPU_BACKEND(...) template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_cpu_backend<__VA_ARGS__>(unsigned, Integrator);

}  // namespace pt
