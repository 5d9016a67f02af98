// The project's own O(1) dispatch over a std::variant: one switch on the alternative's index, no function
// pointers (std::visit may use a table of them, which accelerators such as GPUs and FPGAs cannot call).
#pragma once

#include <cstddef>
#include <type_traits>
#include <variant>

#include "kernel/platform.hpp"

namespace pt {

namespace detail {
template <std::size_t I, class F, class V>
PT_HD inline decltype(auto) call_alternative(F& f, V& v) {
  return f(*std::get_if<I>(&v));
}
}  // namespace detail

// Calls f with the active alternative of v. Supports up to eight alternatives; a larger variant fails to
// compile rather than silently falling back to std::visit.
template <class F, class V>
PT_HD inline decltype(auto) visit(F&& f, V& v) {
  using Plain = std::remove_cv_t<V>;
  constexpr std::size_t count = std::variant_size_v<Plain>;
  static_assert(count >= 1 && count <= 8, "pt::visit handles variants of one to eight alternatives");
  // Indices past the last alternative cannot occur; they share the last case so that the switch has no
  // undefined path for the optimiser to exploit.
  switch (v.index()) {
#define PT_VISIT_CASE(I)                                                   \
  case I:                                                                  \
    if constexpr (I + 1 < count) return detail::call_alternative<I>(f, v); \
    [[fallthrough]];
    PT_VISIT_CASE(0)
    PT_VISIT_CASE(1)
    PT_VISIT_CASE(2)
    PT_VISIT_CASE(3)
    PT_VISIT_CASE(4)
    PT_VISIT_CASE(5)
    PT_VISIT_CASE(6)
#undef PT_VISIT_CASE
    default: return detail::call_alternative<count - 1>(f, v);
  }
}

}  // namespace pt
