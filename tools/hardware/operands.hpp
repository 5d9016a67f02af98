// The operand sets of the hardware units: which kernel values, in which order (the order of the units' ports), how a
// recorder packs them from the kernel's structs, and the C++ model of each unit: the kernel function itself, called
// on the unpacked values. The model is also what the units are made from: record_graphs.cpp runs it on a scalar type
// that records each operation, and tools/hardware/units.py writes the recorded dataflow as Verilog.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "kernel/bvh.hpp"
#include "kernel/fixed_point.hpp"

namespace pt::hardware {

using i64 = std::int64_t;

template <class T>
i64 raw(T v) {
  return static_cast<i64>(v.raw);
}
template <class T>
T value(i64 r) {
  return T::from_raw(static_cast<typename T::Storage>(r));
}
// A float's raw value is its bit pattern, sign-extended from 32 bits as the testbench reads a unit's outputs.
inline i64 raw(float v) {
  std::uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  return static_cast<std::int32_t>(bits);
}
template <>
inline float value<float>(i64 r) {
  const std::uint32_t bits = static_cast<std::uint32_t>(r);
  float v;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}
template <class T>
void put(i64*& out, const Vec3<T>& v) {
  *out++ = raw(v.x);
  *out++ = raw(v.y);
  *out++ = raw(v.z);
}
template <class T>
void put(i64*& out, T v) {
  *out++ = raw(v);
}
template <class T>
Vec3<T> get3(const i64*& in) {
  const Vec3<T> v{value<T>(in[0]), value<T>(in[1]), value<T>(in[2])};
  in += 3;
  return v;
}
template <class T>
T get1(const i64*& in) {
  return value<T>(*in++);
}

// Outputs: the hit flag first, then the values the kernel writes. `always_written` says whether those values are
// written on a miss too (the box's entry distance) or only on a hit (a primitive's Hit fields).
struct BoxOperands {
  static constexpr std::string_view kName = "box";
  static constexpr std::array<std::string_view, 14> kInputs = {
      "inv_direction_x", "inv_direction_y", "inv_direction_z", "origin_term_x", "origin_term_y", "origin_term_z", "near_bound_x",
      "near_bound_y",    "near_bound_z",    "far_bound_x",     "far_bound_y",   "far_bound_z",   "t_min",         "t_max"};
  static constexpr std::array<std::string_view, 2> kOutputs = {"hit", "t_entry"};
  static constexpr bool kAlwaysWritten = true;
  static constexpr int kFirstExtent = 0, kExtents = 0;

  // A box test as ray_hits_box makes it: the ray's slab form, the node, the distance range.
  template <class T>
  static void pack(const BoxRay<T>& r, const BvhNode<T>& node, T t_min, T t_max, i64* out) {
    put(out, r.inv_direction);
    put(out, r.origin_term);
    put(out, Vec3<T>{node_bound(node, r.near_x), node_bound(node, r.near_y), node_bound(node, r.near_z)});
    put(out, Vec3<T>{node_bound(node, r.far_x), node_bound(node, r.far_y), node_bound(node, r.far_z)});
    put(out, t_min);
    put(out, t_max);
  }
  // The node rebuilt with the near bounds as lo and the far ones as hi, and the BoxRay's plane offsets pointing there:
  // ray_hits_box reads the same six bounds it read in the render.
  template <class T>
  static void model(const i64* in, i64* out) {
    BoxRay<T> r;
    r.inv_direction = get3<T>(in);
    r.origin_term = get3<T>(in);
    BvhNode<T> node{};
    node.lo = get3<T>(in);
    node.hi = get3<T>(in);
    const T t_min = get1<T>(in), t_max = get1<T>(in);
    constexpr u32 lo = offsetof(BvhNode<T>, lo), hi = offsetof(BvhNode<T>, hi);
    r.near_x = lo + offsetof(Vec3<T>, x), r.near_y = lo + offsetof(Vec3<T>, y), r.near_z = lo + offsetof(Vec3<T>, z);
    r.far_x = hi + offsetof(Vec3<T>, x), r.far_y = hi + offsetof(Vec3<T>, y), r.far_z = hi + offsetof(Vec3<T>, z);
    T t_entry;
    out[0] = ray_hits_box(node, r, t_min, t_max, t_entry);
    out[1] = raw(t_entry);
  }
};

struct TriangleOperands {
  static constexpr std::string_view kName = "triangle";
  static constexpr std::array<std::string_view, 17> kInputs = {"p0_x",        "p0_y",        "p0_z",        "edge1_x",  "edge1_y",  "edge1_z",
                                                               "edge2_x",     "edge2_y",     "edge2_z",     "origin_x", "origin_y", "origin_z",
                                                               "direction_x", "direction_y", "direction_z", "t_min",    "t_max"};
  static constexpr std::array<std::string_view, 4> kOutputs = {"hit", "t", "b1", "b2"};
  static constexpr bool kAlwaysWritten = false;
  static constexpr int kFirstExtent = 0, kExtents = 0;

  template <class T>
  static void pack(const Triangle<T>& tri, const Ray<T>& ray, T t_min, T t_max, i64* out) {
    put(out, tri.p0);
    put(out, tri.edge1);
    put(out, tri.edge2);
    put(out, ray.origin);
    put(out, ray.direction);
    put(out, t_min);
    put(out, t_max);
  }
  template <class T>
  static void model(const i64* in, i64* out) {
    Triangle<T> tri;
    tri.p0 = get3<T>(in);
    tri.edge1 = get3<T>(in);
    tri.edge2 = get3<T>(in);
    tri.attributes = -1;
    Ray<T> ray{};
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    const T t_min = get1<T>(in), t_max = get1<T>(in);
    Hit<T> hit{};
    out[0] = intersect_triangle(tri, ray, t_min, t_max, hit);
    out[1] = raw(hit.t), out[2] = raw(hit.b1), out[3] = raw(hit.b2);
  }
};

struct QuadOperands {
  static constexpr std::string_view kName = "quad";
  static constexpr std::array<std::string_view, 22> kInputs = {
      "corner_x", "corner_y", "corner_z", "normal_x", "normal_y", "normal_z", "du_x",        "du_y",        "du_z",        "dv_x",  "dv_y",
      "dv_z",     "u_extent", "v_extent", "origin_x", "origin_y", "origin_z", "direction_x", "direction_y", "direction_z", "t_min", "t_max"};
  // The extents' raw values are powers of two (flatten_scene stores them so; the unit divides by them with a shift).
  static constexpr int kFirstExtent = 12, kExtents = 2;
  static constexpr std::array<std::string_view, 4> kOutputs = {"hit", "t", "b1", "b2"};
  static constexpr bool kAlwaysWritten = false;

  template <class T>
  static void pack(const Quad<T>& q, const Ray<T>& ray, T t_min, T t_max, i64* out) {
    put(out, q.corner);
    put(out, q.normal);
    put(out, q.du);
    put(out, q.dv);
    put(out, q.u_extent);
    put(out, q.v_extent);
    put(out, ray.origin);
    put(out, ray.direction);
    put(out, t_min);
    put(out, t_max);
  }
  template <class T>
  static void model(const i64* in, i64* out) {
    Quad<T> q;
    q.corner = get3<T>(in);
    q.normal = get3<T>(in);
    q.du = get3<T>(in);
    q.dv = get3<T>(in);
    q.u_extent = get1<T>(in);
    q.v_extent = get1<T>(in);
    Ray<T> ray{};
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    const T t_min = get1<T>(in), t_max = get1<T>(in);
    Hit<T> hit{};
    out[0] = intersect_quad(q, ray, t_min, t_max, hit);
    out[1] = raw(hit.t), out[2] = raw(hit.b1), out[3] = raw(hit.b2);
  }
};

struct SphereOperands {
  static constexpr std::string_view kName = "sphere";
  static constexpr std::array<std::string_view, 12> kInputs = {"center_x", "center_y",    "center_z",    "radius",      "origin_x", "origin_y",
                                                               "origin_z", "direction_x", "direction_y", "direction_z", "t_min",    "t_max"};
  static constexpr std::array<std::string_view, 4> kOutputs = {"hit", "t", "b1", "b2"};
  static constexpr bool kAlwaysWritten = false;
  static constexpr int kFirstExtent = 0, kExtents = 0;

  // The centre as intersect_sphere is given it (a moving sphere's at the ray's time).
  template <class T>
  static void pack(const Vec3<T>& center, T radius, const Ray<T>& ray, T t_min, T t_max, i64* out) {
    put(out, center);
    put(out, radius);
    put(out, ray.origin);
    put(out, ray.direction);
    put(out, t_min);
    put(out, t_max);
  }
  template <class T>
  static void model(const i64* in, i64* out) {
    const Vec3<T> center = get3<T>(in);
    const T radius = get1<T>(in);
    Ray<T> ray{};
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    const T t_min = get1<T>(in), t_max = get1<T>(in);
    Hit<T> hit{};
    out[0] = intersect_sphere(center, radius, ray, t_min, t_max, hit);
    out[1] = raw(hit.t), out[2] = raw(hit.b1), out[3] = raw(hit.b2);
  }
};

// The traversal engine's other units (src/backends/rtl/traversal_engine.v). Outputs that are not named "hit" first are
// always written; `kOnlyOnHit` marks those that mean something only where the unit reports a hit.

// A ray's slab reciprocals, as make_box_ray forms them for the binary tree.
struct RaySetupOperands {
  static constexpr std::string_view kName = "ray_setup";
  static constexpr std::array<std::string_view, 3> kInputs = {"direction_x", "direction_y", "direction_z"};
  static constexpr std::array<std::string_view, 3> kOutputs = {"inv_x", "inv_y", "inv_z"};
  template <class T>
  static void model(const i64* in, i64* out) {
    Ray<T> ray{};
    ray.direction = get3<T>(in);
    const Vec3<T> inv = slab_reciprocals(ray);
    put(out, inv);
  }
};

// A sphere at its place at the ray's time, as intersect_geometry tests a moving one; a standing sphere is one with
// velocity 0 and time0 0 (the product is 0 and the sum the centre, exactly).
struct MovingSphereOperands {
  static constexpr std::string_view kName = "moving_sphere";
  static constexpr std::array<std::string_view, 17> kInputs = {
      "center0_x", "center0_y", "center0_z", "radius",      "velocity_x",  "velocity_y",  "velocity_z", "time0", "ray_time",
      "origin_x",  "origin_y",  "origin_z",  "direction_x", "direction_y", "direction_z", "t_min",      "t_max"};
  static constexpr std::array<std::string_view, 4> kOutputs = {"hit", "t", "b1", "b2"};
  static constexpr std::array<bool, 4> kOnlyOnHit = {false, true, true, true};
  template <class T>
  static void model(const i64* in, i64* out) {
    MovingSphere<T> s;
    s.center0 = get3<T>(in);
    s.radius = get1<T>(in);
    s.velocity = get3<T>(in);
    s.time0 = get1<T>(in);
    Ray<T> ray{};
    ray.time = get1<T>(in);
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    const T t_min = get1<T>(in), t_max = get1<T>(in);
    Hit<T> hit{};
    out[0] = intersect_sphere(moving_sphere_center(s, ray.time), s.radius, ray, t_min, t_max, hit);
    out[1] = raw(hit.t), out[2] = raw(hit.b1), out[3] = raw(hit.b2);
  }
};

// A world ray taken into a mesh instance's space; an instance without a transform is one with the identity (1 x rounds
// to x, 0 y is 0, exactly).
struct InstanceRayOperands {
  static constexpr std::string_view kName = "instance_ray";
  static constexpr std::array<std::string_view, 18> kInputs = {
      "row0_x",        "row0_y",        "row0_z",   "row1_x",   "row1_y",   "row1_z",      "row2_x",      "row2_y",      "row2_z",
      "translation_x", "translation_y", "translation_z", "origin_x", "origin_y", "origin_z", "direction_x", "direction_y", "direction_z"};
  static constexpr std::array<std::string_view, 6> kOutputs = {"local_origin_x", "local_direction_x", "local_origin_y",
                                                               "local_direction_y", "local_origin_z", "local_direction_z"};
  template <class T>
  static void model(const i64* in, i64* out) {
    InstanceTransform<T> transform{};
    for (Vec3<T>& row : transform.to_mesh.row) row = get3<T>(in);
    transform.to_mesh.translation = get3<T>(in);
    Ray<T> ray{};
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    MeshData<T> meshes{};
    meshes.transforms = &transform;
    const Ray<T> local = instance_ray(meshes, MeshInstance<T>{0, 0}, ray);
    out[0] = raw(local.origin.x), out[1] = raw(local.direction.x), out[2] = raw(local.origin.y);
    out[3] = raw(local.direction.y), out[4] = raw(local.origin.z), out[5] = raw(local.direction.z);
  }
};

// Where the line of a ray crosses a medium's spherical boundary (widen_to_crossings).
struct SphereCrossingsOperands {
  static constexpr std::string_view kName = "sphere_crossings";
  static constexpr std::array<std::string_view, 10> kInputs = {"origin_x",    "origin_y", "origin_z", "direction_x", "direction_y",
                                                               "direction_z", "center_x", "center_y", "center_z",    "radius"};
  static constexpr std::array<std::string_view, 3> kOutputs = {"hit", "near", "far"};
  static constexpr std::array<bool, 3> kOnlyOnHit = {false, true, true};
  template <class T>
  static void model(const i64* in, i64* out) {
    Ray<T> ray{};
    ray.origin = get3<T>(in);
    ray.direction = get3<T>(in);
    const Vec3<T> center = get3<T>(in);
    const T radius = get1<T>(in);
    T near(0), far(0);
    out[0] = sphere_roots(center, radius, ray, near, far);
    out[1] = raw(near), out[2] = raw(far);
  }
};

// What a medium does to a ray once its boundary's crossings are known (medium_event, from t_min 0): a shadow ray
// (`shadow` not 0) gets the optical depth it adds, another the free-flight distance drawn beside it tested.
struct MediumOperands {
  static constexpr std::string_view kName = "medium";
  static constexpr std::array<std::string_view, 7> kInputs = {"first", "last", "t_max", "distance", "neg_inv_density", "optical_depth", "shadow"};
  static constexpr std::array<std::string_view, 3> kOutputs = {"hit", "t", "optical_depth_out"};
  static constexpr std::array<bool, 3> kOnlyOnHit = {false, true, false};
  template <class T>
  static void model(const i64* in, i64* out) {
    const T first = get1<T>(in), last = get1<T>(in), t_max = get1<T>(in), distance = get1<T>(in);
    const T neg_inv_density = get1<T>(in);
    T optical_depth = get1<T>(in);
    const bool shadow = get1<T>(in) != T(0);
    Hit<T> hit{};
    out[0] = medium_event(first, last, T(0), t_max, neg_inv_density, shadow ? &optical_depth : nullptr, [&] { return distance; }, hit);
    out[1] = raw(hit.t), out[2] = raw(optical_depth);
  }
};

// The stream a recorder writes and a testbench reads: this header, then `count` operand sets of `values` raw values
// (int64, host byte order) each.
struct StreamHeader {
  char magic[8];  // "PTOPS1" and two zero bytes
  char unit[16];
  std::int32_t integer_bits, fraction_bits;
  std::int32_t values;
  std::int32_t reserved;
};
inline constexpr char kStreamMagic[8] = {'P', 'T', 'O', 'P', 'S', '1', 0, 0};

}  // namespace pt::hardware
