// The CPU backend for double (a translation unit of its own: see cpu_backend_impl.hpp).
#include "backends/cpu/cpu_backend_impl.hpp"

namespace pt {

template std::unique_ptr<RenderBackend<double>> make_cpu_backend<double>(unsigned, Integrator);

}  // namespace pt
