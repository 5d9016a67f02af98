// Building the bounding-volume hierarchy on the host: binned surface-area heuristic, flattened depth-first.
#pragma once

#include <vector>

#include "kernel/bvh.hpp"

namespace pt {

struct Aabb {
  Vec3<double> lo{largest<double>(), largest<double>(), largest<double>()};
  Vec3<double> hi{-largest<double>(), -largest<double>(), -largest<double>()};

  void grow(const Vec3<double>& p) {
    lo = vmin(lo, p);
    hi = vmax(hi, p);
  }
  void grow(const Aabb& b) {
    lo = vmin(lo, b.lo);
    hi = vmax(hi, b.hi);
  }
  bool empty() const { return lo.x > hi.x; }
  double surface_area() const {
    if (empty()) return 0;
    const Vec3<double> d = hi - lo;
    return 2 * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
  Vec3<double> centroid() const { return (lo + hi) * 0.5; }
};

struct BuiltBvh {
  std::vector<BvhNode<double>> nodes;  // depth-first: a node's first child follows it
  std::vector<u32> order;              // primitive order the leaves refer to
  u32 depth = 0;
};

// Builds over the given primitive bounds. Leaves hold at most kMaxLeafSize primitives, except where the depth
// limit (kBvhMaxDepth) or identical centroids force a larger leaf.
BuiltBvh build_bvh(const std::vector<Aabb>& bounds);

inline constexpr u32 kMaxLeafSize = 4;

// The cost model the wide tree (WideBvhNode) is folded from the binary one with: the expected work of a ray is
// kWideNodeCost for each wide node it visits and kWidePrimitiveCost for each primitive it tests, and a ray visits a
// node or leaf with a probability proportional to the surface area of its box. On the seed's scene, primitive
// weights from 1 to 2 give the same tree (docs/performance-notes.md).
inline constexpr double kWideNodeCost = 1.0;
inline constexpr double kWidePrimitiveCost = 1.0;

}  // namespace pt
