// The rtl backend for the formats its engine was built in (the generated rtl_models.hpp includes each format's
// Verilated model and lists the formats).
#include "backends/rtl/rtl_backend.hpp"

#include <fmt/format.h>

#include "backends/device_backend.hpp"
#include "backends/rtl/rtl_device.hpp"
#include "base/number_formats.hpp"
#include "base/scalar_types.hpp"
#include "rtl_models.hpp"  // PT_FOR_EACH_RTL_MODEL(X): X(I, F, model class) per format

namespace pt {

namespace {

template <class T>
struct EngineModel {
  using type = void;
};
#define PT_RTL_MODEL_OF(I, F, Model) \
  template <>                        \
  struct EngineModel<Fixed<I, F>> {  \
    using type = Model;              \
  };
PT_FOR_EACH_RTL_MODEL(PT_RTL_MODEL_OF)
#undef PT_RTL_MODEL_OF

}  // namespace

std::string rtl_formats() {
  std::string names;
#define PT_RTL_FORMAT_NAME(I, F, Model) names += (names.empty() ? "" : ", ") + number_format_name<Fixed<I, F>>();
  PT_FOR_EACH_RTL_MODEL(PT_RTL_FORMAT_NAME)
#undef PT_RTL_FORMAT_NAME
  return names;
}

template <class T>
std::unique_ptr<RenderBackend<T>> make_rtl_backend(unsigned threads, Integrator integrator) {
  using Model = typename EngineModel<T>::type;
  if constexpr (std::is_void_v<Model>) {
    (void)threads;
    (void)integrator;
    throw BackendError(fmt::format("the rtl backend's traversal engine computes in fixed point, and is built for {} (--number-format); not for {}",
                                   rtl_formats(), number_format_name<T>()));
  } else {
    if (integrator != Integrator::kWavefront)
      throw BackendError("the rtl backend runs the wavefront integrator only (its engine is the intersect stage): --integrator wavefront or auto");
    return std::make_unique<DeviceBackend<RtlDevice<T, Model>, T>>(Integrator::kWavefront, threads);
  }
}

#define PT_INSTANTIATE_RTL_BACKEND(...) template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_rtl_backend<__VA_ARGS__>(unsigned, Integrator);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_RTL_BACKEND)

}  // namespace pt
