// The number formats the renderer is built for (float, double and the fixed-point formats chosen when
// configuring), their names, and running a function template for the format a name picks.
#pragma once

#include <string>
#include <vector>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "base/scalar_types.hpp"
#include "kernel/fixed_point.hpp"

namespace pt {

template <class T>
std::string number_format_name() {
  if constexpr (std::is_same_v<T, float>)
    return "float";
  else if constexpr (std::is_same_v<T, double>)
    return "double";
  else
    return fmt::format("q{}.{}", T::kIntegerBits, T::kFractionBits);
}

// Bits of a value in the format (what a hardware designer pays for).
template <class T>
int number_format_bits() {
  if constexpr (is_fixed_v<T>)
    return T::kTotalBits;
  else
    return static_cast<int>(8 * sizeof(T));
}

inline std::vector<std::string> number_format_names() {
  std::vector<std::string> names;
#define PT_NAME_FORMAT(...) names.push_back(number_format_name<__VA_ARGS__>());
  PT_FOR_EACH_SCALAR_TYPE(PT_NAME_FORMAT)
#undef PT_NAME_FORMAT
  return names;
}

// Calls fn.template operator()<T>() with the format named `name`; throws InputError for an unknown name.
template <class Fn>
decltype(auto) with_number_format(const std::string& name, Fn&& fn) {
#define PT_PICK_FORMAT(...) \
  if (name == number_format_name<__VA_ARGS__>()) return fn.template operator()<__VA_ARGS__>();
  PT_FOR_EACH_SCALAR_TYPE(PT_PICK_FORMAT)
#undef PT_PICK_FORMAT
  throw InputError(fmt::format("unknown number format '{}'", name));
}

}  // namespace pt
