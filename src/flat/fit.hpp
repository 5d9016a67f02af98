// Conversion of the parsed scene's values (double) to the kernels' scalar type, refusing with a located error what
// the type cannot hold or the kernels' arithmetic would overflow. Shared by the parts of flattening (flatten.cpp,
// mesh_tables.cpp, wide_bvh_builder.cpp).
#pragma once

#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "base/number_formats.hpp"
#include "kernel/fixed_point.hpp"
#include "scene/scene.hpp"

namespace pt {

// ---- Supported ranges ----
//
// Every value the kernels get passes through Fit below, which refuses, with one InputError naming the file, line,
// column and JSON path where it was written, a value the scalar type cannot hold or that the kernels' arithmetic
// would overflow. What a value is decides its range:
enum class Quantity {
  kLength,         // coordinates and lengths: positions, radii, edges, velocities, 1 / density, the camera's
  kTriangleEdge,   // a triangle's edges, a length raised to the fourth power (see below)
  kInverseLength,  // per unit length: a quad's dual edges, checker frequencies, noise scales
  kColour,         // colours and emission (radiance)
  kPlain,          // without unit: times, indices of refraction, fuzz, texture coordinates and repeats
};

// Float and double. The scene being finite (the parser refuses the rest) is not enough: the kernels raise lengths to
// powers and multiply radiance along a path, and a result past the largest value (below 2^E: 2^128 for float,
// 2^1024 for double) becomes infinite, so the object silently vanishes or every sample is dropped as non-finite.
// With every stored length and coordinate at most L, every point the kernels compute lies within a few L (a quad's
// far corner, corner + u + v, within 3 L; a ray's origin, a hit point or look_from plus the lens, as much), and:
//   - the BVH slab test, bound * (1 / d) - origin * (1 / d), where slab_reciprocal lets 1 / d reach 1e20 (2^66.5),
//     forms products up to 3 L 2^66.5 and their difference, up to 6 L 2^66.5;
//   - the sphere test, radius * radius - length_squared(perpendicular), squares distances of up to 4 L per axis:
//     up to 48 L^2.
// L = 2^(E/2 - 8) keeps all of these at least 7 times below the largest value: float 2^56 (about 7.2e16), double
// 2^504 (about 5.2e151).
// Triangles go further. Their normal normalises cross(edge1, edge2), whose squared length is a fourth power of the
// edges, up to 12 T^4 for edges at most T; their distance, dot(edge2, cross(origin - p0, edge1)), reaches 24 L T^2.
// T = 2^(E/4 - 2) keeps 12 T^4 a factor 21 below the largest value, and 24 L T^2 a factor 2^7: float 2^30 (about
// 1.07e9), double 2^254.
// A sample's radiance is a sum over up to kMaxDepth = 10000 (< 2^14) bounces of an emission times the throughput,
// a product of the colours met; with emission and throughput at most R, R^2 2^14 must stay below 2^E:
// R = 2^floor((E - 15) / 2), float 2^56, double 2^504. (Colours are albedos, at most 1 in a physical scene, so the
// throughput of a long path stays within R.)
// Other values need only fit the type. Fixed point saturates instead of overflowing, and flatten_scene scales lengths
// by a power of two so that squared distances fit; there every value, after that scaling, must fit the format.
template <class T>
double supported_limit(Quantity q) {
  if constexpr (is_fixed_v<T>) {
    return static_cast<double>(largest<T>());
  } else {
    constexpr int exponent = std::numeric_limits<T>::max_exponent;  // E: the largest value lies below 2^E
    if (q == Quantity::kLength) return std::ldexp(1.0, exponent / 2 - 8);
    if (q == Quantity::kTriangleEdge) return std::ldexp(1.0, exponent / 4 - 2);
    if (q == Quantity::kColour) return std::ldexp(1.0, (exponent - 15) / 2);
    return static_cast<double>(largest<T>());
  }
}

inline const char* quantity_name(Quantity q) {
  switch (q) {
    case Quantity::kLength: return "lengths and coordinates";
    case Quantity::kTriangleEdge: return "triangle edges";
    case Quantity::kColour: return "colours and emission";
    default: return "values";
  }
}

// The spacing of T's values near `magnitude`: one ulp in floating point, one step in fixed point. A value whose effect
// is finer than this where it acts (a pixel's footprint on the image plane, a checker cell at the scene's
// coordinates) vanishes in T, and is refused like a value out of range.
template <class T>
double spacing(double magnitude) {
  // Fixed point: one step (ScalarTraits' rounding step; its rounding unit bounds the error of products, not the
  // spacing of values). Floating point: twice the unit roundoff, relative.
  if constexpr (is_fixed_v<T>) return static_cast<double>(ScalarTraits<T>::rounding_step());
  return 2 * static_cast<double>(ScalarTraits<T>::rounding_unit()) * std::abs(magnitude);
}

// Where a pointer's components are: "/center" -> "/center/0".
inline std::string component(const std::string& pointer, int i) { return pointer + "/" + std::to_string(i); }

// Conversion to the kernels' scalar type, refusing what does not fit (see supported_limit). Lengths arrive already
// multiplied by the scene's scale; messages show them as written, and the scaled value.
template <class T>
class Fit {
 public:
  Fit(const SceneDescription& scene, double scale) : scene_(scene), scale_(scale) {}

  // `pointer`: the JSON path where the value was written; `note`: what the value is, where it is not that written
  // value itself (a position after a transform, 1 / density, ...).
  T operator()(double value, Quantity q, const std::string& pointer, const std::string& note = "") const {
    if (!(std::abs(value) <= supported_limit<T>(q))) refuse(value, q, pointer, note);
    return static_cast<T>(value);
  }
  // A vector: as written (no note), each component is named by its own path, /0, /1 or /2.
  Vec3<T> operator()(const Vec3d& v, Quantity q, const std::string& pointer, const std::string& note = "") const {
    auto one = [&](double x, int i) { return (*this)(x, q, note.empty() ? component(pointer, i) : pointer, note); };
    return {one(v.x, 0), one(v.y, 1), one(v.z, 2)};
  }

  // A texture's or a material's JSON path, or a description where the scene was made in code.
  std::string texture(u32 i) const { return i < scene_.written.textures.size() ? scene_.written.textures[i] : fmt::format("(texture {})", i); }
  std::string material(u32 i) const { return i < scene_.written.materials.size() ? scene_.written.materials[i] : fmt::format("(material {})", i); }
  double scale() const { return scale_; }

  // Refuses what `pointer` says with `reason`, placed as values out of range are.
  [[noreturn]] void fail(const std::string& pointer, const std::string& reason) const {
    if (pointer.empty()) throw InputError(fmt::format("{}: {}", scene_.source, reason));
    throw InputError(fmt::format("{}: {}: {}", source_position(scene_, pointer), pointer, reason));
  }

 private:
  [[noreturn]] void refuse(double value, Quantity q, const std::string& pointer, const std::string& note) const {
    const std::string type = number_format_name<T>();
    const double limit = supported_limit<T>(q);
    const std::string what = note.empty() ? "" : " (" + note + ")";
    const bool length = q == Quantity::kLength || q == Quantity::kTriangleEdge;
    const bool scaled = scale_ != 1 && (length || q == Quantity::kInverseLength);
    const double written = !scaled ? value : length ? value / scale_ : value * scale_;
    const std::string after = scaled ? fmt::format(", {:g} after scaling lengths by {:g},", value, scale_) : "";
    std::string reason;
    if constexpr (is_fixed_v<T>)
      reason = fmt::format("{:g}{}{} does not fit {} (|x| <= {:g}; see docs/numerics.md)", written, what, after, type, limit);
    else if (q != Quantity::kInverseLength && q != Quantity::kPlain)
      reason = fmt::format("{:g}{}{} is beyond {}'s supported range for {} (|x| <= {:.3g}; see docs/scene-format.md)", written, what, after, type,
                           quantity_name(q), limit);
    else
      reason = fmt::format("{:g}{}{} is beyond {}'s range (|x| <= {:.3g})", written, what, after, type, limit);
    fail(pointer, reason);
  }

  const SceneDescription& scene_;
  double scale_;
};

// A value of the BVH or of a fixed table: derived from values Fit has passed (bounds within a few L, unit vectors),
// so it fits; should it not, flatten_scene turns this into an InputError naming the scene.
struct DoesNotFit {
  double value;
};

template <class T>
T scalar(double v) {
  if constexpr (is_fixed_v<T>) {
    if (!(std::abs(v) <= static_cast<double>(largest<T>()))) throw DoesNotFit{v};
  }
  return static_cast<T>(v);
}

template <class T>
Vec3<T> to(const Vec3d& v) {
  return {scalar<T>(v.x), scalar<T>(v.y), scalar<T>(v.z)};
}

}  // namespace pt
