// Backend selection by name.
#include "app/backends.hpp"

#include <fmt/format.h>
#include <tbb/task_arena.h>

#include "backends/cpu/cpu_backend.hpp"
#include "base/number_formats.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif
#if PT_HAVE_SYCL
#include "backends/sycl/sycl_backend.hpp"
#endif

namespace pt {

std::vector<std::string> backend_names() {
  std::vector<std::string> names{"cpu", "auto"};
#if PT_HAVE_CUDA
  names.push_back("cuda");
#endif
#if PT_HAVE_SYCL
  names.push_back("sycl");
#endif
  return names;
}

std::string backend_choices() {
  std::string out;
  for (const std::string& n : backend_names()) out += (out.empty() ? "" : ", ") + n;
  return out;
}

template <class T>
std::unique_ptr<RenderBackend<T>> make_backend(const std::string& name, unsigned threads, int device, Integrator integrator,
                                               int sycl_device) {
  if constexpr (is_fixed_v<T>) {
    // The GPU backends are built for float and double only: fixed-point formats are explored on the host.
    (void)device;
    (void)sycl_device;
    if (name != "cpu" && name != "auto") throw BackendError(fmt::format("number format {} renders on the cpu backend only", number_format_name<T>()));
    return make_cpu_backend<T>(threads, integrator);
  } else {
#if PT_HAVE_SYCL
    if (name == "sycl") return make_sycl_backend<T>(sycl_device, integrator);
#else
    (void)sycl_device;
#endif
#if PT_HAVE_CUDA
    if (name == "cuda") return make_cuda_backend<T>(device, integrator);
    if (name == "auto") {
      if (cuda_device_count() > 0) {
        fmt::print(stderr, "backend auto: using cuda\n");
        return make_cuda_backend<T>(device, integrator);
      }
      fmt::print(stderr, "backend auto: no usable GPU, using cpu\n");
    }
#else
    (void)device;
    if (name == "auto") fmt::print(stderr, "backend auto: built without GPU backends, using cpu\n");
#endif
    return make_cpu_backend<T>(threads, integrator);
  }
}

#define PT_INSTANTIATE_BACKEND(...) \
  template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_backend<__VA_ARGS__>(const std::string&, unsigned, int, Integrator, int);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_BACKEND)

void list_devices() {
  fmt::print("cpu: {} hardware threads\n", tbb::this_task_arena::max_concurrency());
#if PT_HAVE_CUDA
  list_cuda_devices();
#else
  fmt::print("cuda: not built\n");
#endif
#if PT_HAVE_SYCL
  list_sycl_devices();
#else
  fmt::print("sycl: not built\n");
#endif
}

}  // namespace pt
