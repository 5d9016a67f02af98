// The CPU backend for the fixed-point formats built in (a translation unit of their own: see cpu_backend_impl.hpp).
#include "backends/cpu/cpu_backend_impl.hpp"

namespace pt {

#define PT_INSTANTIATE_FIXED_CPU_BACKEND(I, F) template std::unique_ptr<RenderBackend<Fixed<I, F>>> make_cpu_backend<Fixed<I, F>>(unsigned, Integrator);
PT_FOR_EACH_FIXED_FORMAT(PT_INSTANTIATE_FIXED_CPU_BACKEND)

}  // namespace pt
