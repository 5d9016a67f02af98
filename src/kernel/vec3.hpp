// Three-component vectors and colours, and the ray, over any scalar type.
#pragma once

#include "kernel/scalar.hpp"

namespace pt {

template <class T>
struct Vec3 {
  T x, y, z;

  PT_HD constexpr Vec3() : x(0), y(0), z(0) {}
  PT_HD constexpr Vec3(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  PT_HD static constexpr Vec3 splat(T v) { return {v, v, v}; }

  PT_HD T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  PT_HD Vec3 operator-() const { return {-x, -y, -z}; }
  PT_HD Vec3& operator+=(const Vec3& o) {
    x += o.x;
    y += o.y;
    z += o.z;
    return *this;
  }
  PT_HD Vec3& operator*=(const Vec3& o) {
    x *= o.x;
    y *= o.y;
    z *= o.z;
    return *this;
  }
  PT_HD Vec3& operator*=(T s) {
    x *= s;
    y *= s;
    z *= s;
    return *this;
  }
};

template <class T>
PT_HD inline Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
template <class T>
PT_HD inline Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
template <class T>
PT_HD inline Vec3<T> operator*(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x * b.x, a.y * b.y, a.z * b.z};
}
template <class T>
PT_HD inline Vec3<T> operator*(const Vec3<T>& a, T s) {
  return {a.x * s, a.y * s, a.z * s};
}
template <class T>
PT_HD inline Vec3<T> operator*(T s, const Vec3<T>& a) {
  return {a.x * s, a.y * s, a.z * s};
}
template <class T>
PT_HD inline Vec3<T> operator/(const Vec3<T>& a, T s) {
  return {a.x / s, a.y / s, a.z / s};
}

template <class T>
PT_HD inline T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class T>
PT_HD inline Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class T>
PT_HD inline T length_squared(const Vec3<T>& a) {
  return dot(a, a);
}
// |a|. Formats with exact products (fixed point, ScalarTraits::kExactProducts) sum the exact squares and round once,
// by the root: the square of a length well inside the range can lie far beyond it (555^2 in Q16.16).
template <class T>
PT_HD inline T length(const Vec3<T>& a) {
  if constexpr (ScalarTraits<T>::kExactProducts) {
    using S = ScalarTraits<T>;
    return S::exact_sqrt(S::exact(a.x) * S::exact(a.x) + S::exact(a.y) * S::exact(a.y) + S::exact(a.z) * S::exact(a.z));
  } else {
    return sqrt(dot(a, a));
  }
}
template <class T>
PT_HD inline Vec3<T> normalize(const Vec3<T>& a) {
  return a / length(a);
}
template <class T>
PT_HD inline Vec3<T> lerp(const Vec3<T>& a, const Vec3<T>& b, T t) {
  return a * (T(1) - t) + b * t;
}
template <class T>
PT_HD inline Vec3<T> vmin(const Vec3<T>& a, const Vec3<T>& b) {
  return {min(a.x, b.x), min(a.y, b.y), min(a.z, b.z)};
}
template <class T>
PT_HD inline Vec3<T> vmax(const Vec3<T>& a, const Vec3<T>& b) {
  return {max(a.x, b.x), max(a.y, b.y), max(a.z, b.z)};
}
template <class T>
PT_HD inline T max_component(const Vec3<T>& a) {
  return max(a.x, max(a.y, a.z));
}
template <class T>
PT_HD inline Vec3<T> vabs(const Vec3<T>& a) {
  return {abs(a.x), abs(a.y), abs(a.z)};
}
// rounding_error component by component.
template <class T>
PT_HD inline Vec3<T> rounding_error(const Vec3<T>& magnitude, T roundings) {
  return {rounding_error(magnitude.x, roundings), rounding_error(magnitude.y, roundings), rounding_error(magnitude.z, roundings)};
}
template <class T>
PT_HD inline bool is_finite(const Vec3<T>& a) {
  return is_finite(a.x) && is_finite(a.y) && is_finite(a.z);
}

// Mirror direction d about the unit normal n.
template <class T>
PT_HD inline Vec3<T> reflect(const Vec3<T>& d, const Vec3<T>& n) {
  return d - constant<T>(2) * dot(d, n) * n;
}

// Refract the unit direction d through the unit normal n (facing d) with relative index eta; cos_i = -dot(d, n).
template <class T>
PT_HD inline Vec3<T> refract(const Vec3<T>& d, const Vec3<T>& n, T eta, T cos_i) {
  const Vec3<T> perpendicular = eta * (d + cos_i * n);
  const T parallel_squared = abs(T(1) - length_squared(perpendicular));
  return perpendicular - sqrt(parallel_squared) * n;
}

template <class T>
using Color = Vec3<T>;

// A ray with a unit-length direction and the instant (within the shutter interval) it was sent.
template <class T>
struct Ray {
  Vec3<T> origin;
  Vec3<T> direction;
  T time;
  PT_HD Vec3<T> at(T t) const { return origin + t * direction; }
};

}  // namespace pt
