// The CPU backend: the kernel headers run on all cores through oneTBB.
#pragma once

#include <memory>

#include "backends/backend.hpp"

namespace pt {

// threads == 0: all cores.
template <class T>
std::unique_ptr<RenderBackend<T>> make_cpu_backend(unsigned threads, Integrator integrator = Integrator::kMegakernel);

}  // namespace pt
