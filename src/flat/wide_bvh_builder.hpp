// The wide BVH the CPU kernels walk (kernel/bvh.hpp, WideBvhNode), folded from the binary one; and the padding of
// a binary node's box that keeps rounding in the kernels' type from making a ray miss it.
#pragma once

#include <algorithm>
#include <vector>

#include "flat/bvh_builder.hpp"
#include "flat/fit.hpp"

namespace pt {

// A node's box in double, its corners multiplied by `scale` (exact: a power of two).
template <class S>
Aabb scaled_box(const BvhNode<S>& n, double scale) {
  const Vec3d lo{n.lo.x, n.lo.y, n.lo.z}, hi{n.hi.x, n.hi.y, n.hi.z};
  return scale == 1 ? Aabb{lo, hi} : Aabb{lo * scale, hi * scale};
}

// Widens a box so that rounding in the kernels' scalar type can never make a ray miss the box of a primitive
// it hits (the BVH must find exactly what brute force finds). The box is the node's multiplied by `scale`.
template <class T, class S>
BvhNode<T> padded_node(const BvhNode<S>& node, double scale = 1) {
  const Aabb n = scaled_box(node, scale);
  const Vec3d extent = n.hi - n.lo;
  const double magnitude = std::max(max_component(vmax(vmax(n.lo, -n.lo), vmax(n.hi, -n.hi))), max_component(extent));
  const double pad = 1e-5 * magnitude + 1e-9;
  BvhNode<T> out;
  out.lo = to<T>(n.lo - Vec3d::splat(pad));
  out.hi = to<T>(n.hi + Vec3d::splat(pad));
  out.left_first = node.left_first;
  out.count = node.count;
  return out;
}

// The wide tree of a binary one built in S (float or double) for kernels of scalar type T, its boxes multiplied by
// `scale` (a power of two) as they are read: see wide_bvh_builder.cpp. `alone_at` (empty: none), indexed as the
// leaves index primitives, marks the primitives that keep a leaf of their own (build_bvh's `alone`).
template <class T, class S>
std::vector<WideBvhNode<T>> build_wide_bvh(const std::vector<BvhNode<S>>& binary, double scale = 1, const std::vector<bool>& alone_at = {});

}  // namespace pt
