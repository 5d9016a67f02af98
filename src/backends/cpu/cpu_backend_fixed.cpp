// The CPU backend for the fixed-point formats built in (a translation unit of their own: see cpu_device.hpp).
#include "backends/cpu/cpu_backend_impl.hpp"

namespace pt {

PT_FOR_EACH_FIXED_TYPE(PT_INSTANTIATE_CPU_BACKEND)

}  // namespace pt
