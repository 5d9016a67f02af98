// The rtl backend: the wavefront integrator with its intersect stage in the traversal engine's cycle-accurate model
// (rtl_device.hpp), for the fixed-point formats the engine is built in (CMake: PT_RTL_FORMATS).
#pragma once

#include <memory>
#include <string>

#include "backends/backend.hpp"

namespace pt {

// Throws BackendError where T is not a format the engine was built in, or for the megakernel.
template <class T>
std::unique_ptr<RenderBackend<T>> make_rtl_backend(unsigned threads, Integrator integrator);

// The formats the engine was built in, as --number-format names them ("q16.16, ...").
std::string rtl_formats();

}  // namespace pt
