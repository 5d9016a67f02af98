// The compressed wide tree (kernel/compressed_bvh.hpp): its boxes hold the wide tree's, its box test never rejects
// a box that exact distances enter, oversized leaves are split, and the walk visits the nearer side of a node first.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "flat/compressed_bvh_builder.hpp"
#include "flat/flat_scene.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

// A wide node whose slots are leaves with the given boxes (lo x, y, z, hi x, y, z), primitives 10 i to 10 i + 9.
WideBvhNode<float> leaf_node(const std::vector<std::array<float, 6>>& boxes) {
  WideBvhNode<float> node{};
  for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
    const std::array<float, 6>& box = boxes[lane < boxes.size() ? lane : 0];
    for (int p = 0; p < 6; ++p) node.bounds[p][lane] = box[p];
    if (lane < boxes.size()) {
      node.child[lane] = 10 * lane;
      node.count[lane] = 10;
      node.leaf_mask |= 1u << lane;
    }
  }
  return node;
}

// Child `slot`'s box as the compressed node holds it, in double: origin + byte * 2^exponent (exact in double).
std::array<double, 6> decoded_box(const CompressedBoxes& boxes, u32 slot) {
  std::array<double, 6> box{};
  for (int p = 0; p < 6; ++p) {
    const int axis = p % 3;
    const u32 word = boxes.planes[2 * p + slot / 4];
    box[p] = static_cast<double>(boxes.origin[axis]) + std::ldexp(static_cast<double>((word >> (8 * (slot % 4))) & 0xffu), boxes.exponent[axis]);
  }
  return box;
}

TEST(CompressedBvh, ChildBoxesHoldTheWideTreesBoxesAndKeepTheirChildren) {
  TestRandom rng(31);
  for (int n = 0; n < 2000; ++n) {
    const Vec3d centre = rng.vec3(-1, 1) * std::pow(10.0, rng.uniform(-3, 5));
    const double size = std::pow(10.0, rng.uniform(-6, 3));
    std::vector<std::array<float, 6>> boxes;
    const u32 children = 1 + rng.below(kWideBvhWidth);
    for (u32 c = 0; c < children; ++c) {
      const Vec3d lo = centre + rng.vec3(-size, size), extent = rng.vec3(0, size) * (rng.uniform() < 0.2 ? 0.0 : 1.0);
      boxes.push_back({static_cast<float>(lo.x), static_cast<float>(lo.y), static_cast<float>(lo.z), static_cast<float>(lo.x + extent.x),
                       static_cast<float>(lo.y + extent.y), static_cast<float>(lo.z + extent.z)});
    }
    const std::vector<CompressedWideNode> compressed = compress_wide_bvh({leaf_node(boxes)});
    ASSERT_EQ(compressed.size(), 1u);
    const CompressedWideNode& node = compressed[0];
    std::vector<bool> seen(children, false);
    for (u32 slot = 0; slot < kCompressedWidth; ++slot) {
      if (node.count[slot] == 0) continue;
      ASSERT_EQ(node.child[slot] % 10, 0u);
      const u32 c = node.child[slot] / 10;
      ASSERT_LT(c, children);
      EXPECT_FALSE(seen[c]) << "child " << c << " in two slots";
      seen[c] = true;
      EXPECT_EQ(node.count[slot], 10u);
      const std::array<double, 6> box = decoded_box(node.boxes, slot);
      for (int a = 0; a < 3; ++a) {
        EXPECT_LE(box[a], boxes[c][a]) << "node " << n << " child " << c << " axis " << a;
        EXPECT_GE(box[3 + a], boxes[c][3 + a]) << "node " << n << " child " << c << " axis " << a;
      }
    }
    EXPECT_EQ(std::count(seen.begin(), seen.end(), true), static_cast<long>(children));
    EXPECT_EQ(node.boxes.inner_mask, 0u);
  }
}

// The property the tree's exactness rests on: where the exact distances to a (decoded) child box, computed with the
// ray's float reciprocal direction, overlap [t_min, closest], the float test enters it too. Rays come from far away
// (up to 10^5 times the boxes' size) and graze the boxes' edges and corners, where rounding decides.
TEST(CompressedBvh, BoxTestEntersEveryBoxTheExactDistancesEnter) {
  TestRandom rng(97);
  int grazing_entries = 0;
  for (int n = 0; n < 400; ++n) {
    const Vec3d centre = rng.vec3(-1, 1) * std::pow(10.0, rng.uniform(-2, 3));
    const double size = std::pow(10.0, rng.uniform(-3, 1));
    std::vector<std::array<float, 6>> boxes;
    for (u32 c = 0; c < kWideBvhWidth; ++c) {
      const Vec3d lo = centre + rng.vec3(-size, size), extent = rng.vec3(0, size);
      boxes.push_back({static_cast<float>(lo.x), static_cast<float>(lo.y), static_cast<float>(lo.z), static_cast<float>(lo.x + extent.x),
                       static_cast<float>(lo.y + extent.y), static_cast<float>(lo.z + extent.z)});
    }
    const CompressedWideNode node = compress_wide_bvh({leaf_node(boxes)})[0];
    for (int r = 0; r < 500; ++r) {
      const u32 slot = rng.below(kCompressedWidth);
      const std::array<double, 6> box = decoded_box(node.boxes, slot);
      // A point on an edge or at a corner of the decoded box, and a ray towards it from far away.
      Vec3d target{};
      for (int a = 0; a < 3; ++a) {
        const double u = rng.uniform() < 0.7 ? std::round(rng.uniform()) : rng.uniform();
        (a == 0 ? target.x : a == 1 ? target.y : target.z) = box[a] + u * (box[3 + a] - box[a]);
      }
      const Vec3d origin = target + rng.unit_vector() * size * std::pow(10.0, rng.uniform(0, 5));
      const Ray<float> ray{test::to<float>(origin), test::to<float>(normalize(target - origin)), 0};
      const CompressedRay cray = make_compressed_ray(ray);
      // Exact distances to the decoded planes with the same float reciprocal (double is exact enough here: its
      // rounding is 2^-29 of float's).
      const double inv[3] = {cray.inv.x, cray.inv.y, cray.inv.z};
      const double o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
      double near = 0, far = 1e30;
      for (int a = 0; a < 3; ++a) {
        const double t0 = (box[a] - o[a]) * inv[a], t1 = (box[3 + a] - o[a]) * inv[a];
        near = std::max(near, std::min(t0, t1));
        far = std::min(far, std::max(t0, t1));
      }
      if (near > far) continue;
      u32 leaves = 0, inner = 0;
      compressed_box_test(node.boxes, cray, 0.0f, 1e30f, leaves, inner);
      EXPECT_TRUE((leaves | inner) >> visit_place(cray, slot) & 1u)
          << "node " << n << " ray " << r << ": slot " << slot << " not entered, exact entry " << near << " exit " << far;
      if (far - near < 1e-6 * far) ++grazing_entries;
    }
  }
  EXPECT_GT(grazing_entries, 1000);  // the cases where rounding decides are there
}

TEST(CompressedBvh, ALeafTooLargeForOneSlotIsSharedOutAmongTheSlotsOfANewNode) {
  std::vector<WideBvhNode<float>> wide{leaf_node({{0, 0, 0, 1, 1, 1}, {2, 0, 0, 3, 1, 1}})};
  wide[0].child[0] = 5;
  wide[0].count[0] = 1'000'000;  // more than eight slots of 65,535: split twice
  wide[0].child[1] = 1'000'005;
  wide[0].count[1] = 3;
  const std::vector<CompressedWideNode> compressed = compress_wide_bvh(wide);
  ASSERT_GT(compressed.size(), 2u);
  // Gather the leaves under the root's slots: the ranges must tile [5, 1'000'008) once each.
  std::vector<std::pair<u32, u32>> ranges;
  std::vector<u32> pending{0};
  while (!pending.empty()) {
    const CompressedWideNode& node = compressed[pending.back()];
    pending.pop_back();
    for (u32 slot = 0; slot < kCompressedWidth; ++slot) {
      if (node.boxes.inner_mask >> slot & 1u)
        pending.push_back(node.child[slot]);
      else if (node.count[slot] > 0)
        ranges.emplace_back(node.child[slot], node.count[slot]);
    }
  }
  std::sort(ranges.begin(), ranges.end());
  u32 next = 5;
  for (const auto& [first, count] : ranges) {
    EXPECT_EQ(first, next);
    next = first + count;
  }
  EXPECT_EQ(next, 1'000'008u);
}

// Children are visited in an order that follows the ray without sorting: along a row of eight boxes on the x axis,
// a ray along +x visits the four nearer boxes before the four farther ones, and a ray along -x the other four first.
TEST(CompressedBvh, TheWalkVisitsTheNearerHalfOfARowFirstFromEitherSide) {
  std::vector<std::array<float, 6>> row;
  for (int i = 0; i < 8; ++i) row.push_back({static_cast<float>(2 * i), 0, 0, static_cast<float>(2 * i + 1), 1, 1});
  const std::vector<CompressedWideNode> compressed = compress_wide_bvh({leaf_node(row)});
  for (const float direction : {1.0f, -1.0f}) {
    std::vector<u32> visited;
    auto leaf = [&](u32 first, u32, float&) {
      visited.push_back(first / 10);
      return false;
    };
    float closest = 1e30f;
    const Ray<float> ray{Vec3<float>{direction > 0 ? -5.0f : 25.0f, 0.5f, 0.5f}, Vec3<float>{direction, 0.01f, 0.02f}, 0};
    walk_compressed(compressed.data(), 0, ray, closest, leaf);
    ASSERT_EQ(visited.size(), 8u) << "direction " << direction;
    for (int k = 0; k < 4; ++k) EXPECT_EQ(visited[k]<4, direction> 0) << "direction " << direction << ", visit " << k;
  }
}

}  // namespace
}  // namespace pt
