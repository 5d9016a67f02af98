// The CPU backend for float, the default scalar type (a translation unit of its own: see cpu_backend_impl.hpp).
#include "backends/cpu/cpu_backend_impl.hpp"

namespace pt {

template std::unique_ptr<RenderBackend<float>> make_cpu_backend<float>(unsigned, Integrator);

}  // namespace pt
