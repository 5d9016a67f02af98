// Building the bounding-volume hierarchy on the host: binned surface-area heuristic, flattened depth-first.
#pragma once

#include <cmath>
#include <vector>

#include "kernel/bvh.hpp"

namespace pt {

// A box in S (double, or float for large meshes: half the memory). Its surface area and centroid are computed in
// double either way, so a float box whose corners are exact gives the builder the same numbers as the double one.
template <class S>
struct Box {
  Vec3<S> lo{largest<S>(), largest<S>(), largest<S>()};
  Vec3<S> hi{-largest<S>(), -largest<S>(), -largest<S>()};

  void grow(const Vec3<S>& p) {
    lo = vmin(lo, p);
    hi = vmax(hi, p);
  }
  void grow(const Box& b) {
    lo = vmin(lo, b.lo);
    hi = vmax(hi, b.hi);
  }
  bool empty() const { return lo.x > hi.x; }
  double surface_area() const {
    if (empty()) return 0;
    const Vec3<double> d = Vec3<double>{hi.x, hi.y, hi.z} - Vec3<double>{lo.x, lo.y, lo.z};
    return 2 * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
  double centroid(int axis) const { return (static_cast<double>(lo[axis]) + static_cast<double>(hi[axis])) * 0.5; }
  Vec3<double> centroid() const { return {centroid(0), centroid(1), centroid(2)}; }
};

using Aabb = Box<double>;
using FloatBox = Box<float>;

// The float box containing a double one: each corner rounded outward (exact where the corners are floats, as the
// vertices of most model files are). Only for boxes within float's range (float_box_fits).
inline FloatBox outward_float_box(const Aabb& b) {
  auto down = [](double x) {
    const float f = static_cast<float>(x);
    return static_cast<double>(f) > x ? std::nextafter(f, -largest<float>()) : f;
  };
  auto up = [](double x) {
    const float f = static_cast<float>(x);
    return static_cast<double>(f) < x ? std::nextafter(f, largest<float>()) : f;
  };
  return FloatBox{{down(b.lo.x), down(b.lo.y), down(b.lo.z)}, {up(b.hi.x), up(b.hi.y), up(b.hi.z)}};
}

// Whether coordinates of at most this magnitude keep their float boxes finite, with room for scaling.
inline bool float_box_fits(double largest_coordinate) { return largest_coordinate <= 0x1p100; }

template <class S>
struct BuiltBvh {
  std::vector<BvhNode<S>> nodes;  // depth-first: a node's first child follows it
  std::vector<u32> order;         // primitive order the leaves refer to
  u32 depth = 0;
};

// Builds over the given primitive bounds. Leaves hold at most kMaxLeafSize primitives, except where the depth
// limit (kBvhMaxDepth) or identical centroids force a larger leaf; a primitive marked in `alone` (empty: none) gets
// a leaf of its own, but where the depth limit forces one. Node boxes are unions of the given boxes (exact in S).
// S: double or float.
template <class S>
BuiltBvh<S> build_bvh(const std::vector<Box<S>>& bounds, const std::vector<bool>& alone = {});

inline constexpr u32 kMaxLeafSize = 4;

// The cost model the wide tree (WideBvhNode) is folded from the binary one with: the expected work of a ray is
// kWideNodeCost for each wide node it visits and kWidePrimitiveCost for each primitive it tests, and a ray visits a
// node or leaf with a probability proportional to the surface area of its box. On the seed's scene, primitive
// weights from 1 to 2 give the same tree (docs/performance-notes.md).
inline constexpr double kWideNodeCost = 1.0;
inline constexpr double kWidePrimitiveCost = 1.0;

}  // namespace pt
