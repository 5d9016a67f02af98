// Binned SAH BVH construction (16 bins per axis over primitive centroids), with large subtrees built in parallel.
#include "flat/bvh_builder.hpp"

#include <algorithm>
#include <array>

#include "base/free_memory.hpp"
#include "base/parallel_loop.hpp"

namespace pt {

namespace {

constexpr int kBins = 16;
// Relative costs of visiting a node and intersecting a primitive, for the SAH.
constexpr double kTraversalCost = 1.0;
constexpr double kIntersectionCost = 1.0;

// Centroids are not stored: each is computed from its box when needed, in double (Box::centroid).
template <class S>
class Builder {
 public:
  using Node = BvhNode<S>;

  Builder(const std::vector<Box<S>>& bounds, const std::vector<bool>& alone) : bounds_(bounds), alone_(alone) {
    result_.order.resize(bounds.size());
    for (u32 i = 0; i < bounds.size(); ++i) result_.order[i] = i;
  }

  BuiltBvh<S> build() {
    result_.nodes.reserve(2 * bounds_.size());
    result_.depth = build_node(0, static_cast<u32>(bounds_.size()), 1, result_.nodes);
    return std::move(result_);
  }

 private:
  // Subtrees of at least this many primitives have their two halves built at once, the second into a list of its
  // own that is appended after the first. Every split is computed exactly as one thread computes it, and the nodes
  // end up in the same depth-first order, so the tree does not depend on the number of threads.
  static constexpr u32 kParallelSubtree = 16384;
  // After merging the second half of a subtree this large, its freed list is given back to the system at once.
  static constexpr u32 kReleaseSubtree = 1u << 18;

  // Whether order[first, first + count) may be one leaf: at most kMaxLeafSize primitives, none of them to be alone.
  bool may_be_leaf(u32 first, u32 count) const {
    if (count > kMaxLeafSize) return false;
    if (count == 1 || alone_.empty()) return true;
    for (u32 i = first; i < first + count; ++i)
      if (alone_[result_.order[i]]) return false;
    return true;
  }

  static void make_leaf(std::vector<Node>& nodes, u32 index, u32 first, u32 count) {
    nodes[index].left_first = first;
    nodes[index].count = count;
  }

  // Builds the subtree over order[first, first + count) at the end of `nodes` (whose indices it uses); returns its depth.
  u32 build_node(u32 first, u32 count, u32 depth, std::vector<Node>& nodes) {
    const u32 index = static_cast<u32>(nodes.size());
    nodes.push_back({});
    Box<S> box;
    Aabb centroid_box;
    for (u32 i = first; i < first + count; ++i) {
      const Box<S>& b = bounds_[result_.order[i]];
      box.grow(b);
      centroid_box.grow(b.centroid());
    }
    nodes[index].lo = box.lo;
    nodes[index].hi = box.hi;
    if (count <= 1 || depth >= kBvhMaxDepth) {
      make_leaf(nodes, index, first, count);
      return depth;
    }

    // Best binned split over the three axes.
    double best_cost = largest<double>();
    int best_axis = -1, best_bin = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double lo = centroid_box.lo[axis], extent = centroid_box.hi[axis] - lo;
      if (!(extent > 0)) continue;
      std::array<Box<S>, kBins> bin_boxes;
      std::array<u32, kBins> bin_counts{};
      for (u32 i = first; i < first + count; ++i) {
        const Box<S>& box_i = bounds_[result_.order[i]];
        const int b = bin_of(box_i.centroid(axis), lo, extent);
        bin_boxes[b].grow(box_i);
        ++bin_counts[b];
      }
      std::array<double, kBins> right_area{};
      std::array<u32, kBins> right_count{};
      Box<S> running;
      u32 running_count = 0;
      for (int b = kBins - 1; b > 0; --b) {
        running.grow(bin_boxes[b]);
        running_count += bin_counts[b];
        right_area[b] = running.surface_area();
        right_count[b] = running_count;
      }
      running = Box<S>{};
      running_count = 0;
      for (int b = 0; b < kBins - 1; ++b) {
        running.grow(bin_boxes[b]);
        running_count += bin_counts[b];
        if (running_count == 0 || right_count[b + 1] == 0) continue;
        const double cost = running.surface_area() * running_count + right_area[b + 1] * right_count[b + 1];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_bin = b;
        }
      }
    }

    const double leaf_cost = kIntersectionCost * count;
    const double split_cost = kTraversalCost + kIntersectionCost * best_cost / std::max(box.surface_area(), 1e-300);
    u32 middle;
    if (best_axis < 0) {
      // All centroids coincide: no split separates them, so halve the list unless it is small.
      if (may_be_leaf(first, count)) {
        make_leaf(nodes, index, first, count);
        return depth;
      }
      middle = first + count / 2;
    } else {
      if (may_be_leaf(first, count) && leaf_cost <= split_cost) {
        make_leaf(nodes, index, first, count);
        return depth;
      }
      const double lo = centroid_box.lo[best_axis], extent = centroid_box.hi[best_axis] - lo;
      const auto it = std::partition(result_.order.begin() + first, result_.order.begin() + first + count,
                                     [&](u32 p) { return bin_of(bounds_[p].centroid(best_axis), lo, extent) <= best_bin; });
      middle = static_cast<u32>(it - result_.order.begin());
    }
    u32 left_depth = 0, right_depth = 0;
    if (count < kParallelSubtree) {
      left_depth = build_node(first, middle - first, depth + 1, nodes);
      nodes[index].left_first = static_cast<u32>(nodes.size());
      right_depth = build_node(middle, first + count - middle, depth + 1, nodes);
    } else {
      std::vector<Node> right_nodes;
      right_nodes.reserve(2 * (first + count - middle));
      parallel_invoke([&] { left_depth = build_node(first, middle - first, depth + 1, nodes); },
                      [&] { right_depth = build_node(middle, first + count - middle, depth + 1, right_nodes); });
      const u32 offset = static_cast<u32>(nodes.size());
      nodes[index].left_first = offset;
      for (Node n : right_nodes) {
        if (n.count == 0) n.left_first += offset;  // an interior node's second child; leaves index primitives
        nodes.push_back(n);
      }
      std::vector<Node>().swap(right_nodes);
      if (count >= kReleaseSubtree) release_free_memory();
    }
    nodes[index].count = 0;
    return std::max(left_depth, right_depth);
  }

  static int bin_of(double value, double lo, double extent) {
    const int b = static_cast<int>((value - lo) / extent * kBins);
    return std::clamp(b, 0, kBins - 1);
  }

  const std::vector<Box<S>>& bounds_;  // read by all threads
  const std::vector<bool>& alone_;     // likewise
  BuiltBvh<S> result_;
};

}  // namespace

template <class S>
BuiltBvh<S> build_bvh(const std::vector<Box<S>>& bounds, const std::vector<bool>& alone) {
  if (bounds.empty()) {
    BuiltBvh<S> empty;
    empty.nodes.push_back(BvhNode<S>{Vec3<S>::splat(1), 0, Vec3<S>::splat(-1), 0});
    return empty;
  }
  return Builder<S>(bounds, alone).build();
}

template BuiltBvh<double> build_bvh<double>(const std::vector<Box<double>>&, const std::vector<bool>&);
template BuiltBvh<float> build_bvh<float>(const std::vector<Box<float>>&, const std::vector<bool>&);

}  // namespace pt
