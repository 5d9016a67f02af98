// The CPU backend for double (a translation unit of its own: see cpu_device.hpp).
#include "backends/cpu/cpu_backend_impl.hpp"

namespace pt {

PT_INSTANTIATE_CPU_BACKEND(double)

}  // namespace pt
