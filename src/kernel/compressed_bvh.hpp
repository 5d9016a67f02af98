// The wide BVH compressed for GPUs (eight children a node, child boxes as bytes on a grid local to the node, after
// Ylitie, Karras and Laine, HPG 2017) and the closest-hit walk over it.
#pragma once

#include <cmath>
#include <cstdint>

#include "kernel/bvh.hpp"

namespace pt {

inline constexpr u32 kCompressedWidth = 8;

// The part of a node every visit reads: 64 bytes, four 16-byte loads. Along axis a, child slot i spans
// origin[a] + q * 2^exponent[a] for q from its lo byte to its hi byte: the child's box rounded outwards to the
// node's grid, so it holds the child (flat/compressed_bvh_builder.cpp). `planes` holds the bytes by plane, four
// slots a word: lo x of slots 0-3, lo x of slots 4-7, then lo y, lo z, hi x, hi y, hi z likewise. inner_mask has
// bit i set where slot i holds an inner node.
struct alignas(16) CompressedBoxes {
  float origin[3];
  std::int8_t exponent[3];
  u8 inner_mask;
  u32 planes[12];
};

// A node: its boxes, then what each slot holds, read only for the slots a ray enters: an inner node's index, or
// a leaf's first primitive and its count (count 0: an empty slot, whose box is empty too). Children are placed in
// slots by where they lie in the node (slot bit 0 for the +x side, bit 1 +y, bit 2 +z, as well as eight children
// allow), so that the walk can visit them roughly nearest first in an order that the ray's direction alone gives
// (CompressedRay), without sorting.
struct alignas(16) CompressedWideNode {
  CompressedBoxes boxes;
  u32 child[kCompressedWidth];
  std::uint16_t count[kCompressedWidth];
};
static_assert(sizeof(CompressedBoxes) == 64);
static_assert(sizeof(CompressedWideNode) == 112, "seven 16-byte loads");

// Byte `index` of `word` as a float (0 to 255).
PT_HD inline float plane_byte(u32 word, u32 index) {
#if defined(__CUDA_ARCH__)
  // One byte permute puts it into the mantissa of 2^23 (bits 0x4B000000), one exact subtraction takes 2^23 away.
  return __uint_as_float(__byte_perm(word, 0x4B000000u, index | 0x7440u)) - 8388608.0f;
#else
  return static_cast<float>((word >> (8 * index)) & 0xffu);
#endif
}

// 2^e as a float, for e from -126 to 127.
PT_HD inline float power_of_two(int e) {
#if defined(__CUDA_ARCH__)
  return __int_as_float((e + 127) << 23);
#else
  return std::ldexp(1.0f, e);
#endif
}

// a * b + c rounded once (explicitly: the kernels are compiled without contraction, and the box test's bound on
// its rounding below counts one rounding here).
PT_HD inline float fused_multiply_add(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
  return __fmaf_rn(a, b, c);
#else
  return std::fma(a, b, c);
#endif
}

// The distances along a ray to a node's planes on one axis: plane q lies at q * scale + base (scale 2^e times the
// reciprocal direction), base being (origin - ray origin) times the reciprocal, less the slack for the near planes
// and plus it for the far ones.
struct AxisPlanes {
  float scale, near_base, far_base;
};

// Rounding makes the computed distance to a plane differ from the exact one for the same reciprocal direction by at
// most about 4 units in the last place of (|node origin| + |ray origin| + 255 * 2^e) * |reciprocal| (a difference,
// a product, the slack's addition, the fused multiply-add): twice that is taken off the near planes and added to
// the far ones, so that a box the exact distances enter is entered (the tree is exact: a hit found by the binary or
// the wide walk is found by this one). 2^-21 = 8 units of 2^-24.
inline constexpr float kPlaneSlack = 4.76837158203125e-7f;

PT_HD inline AxisPlanes axis_planes(float node_origin, int exponent, float ray_origin, float reciprocal) {
  const float grid = power_of_two(exponent);
  const float base = (node_origin - ray_origin) * reciprocal;
  const float slack = kPlaneSlack * ((::fabsf(node_origin) + ::fabsf(ray_origin)) + 255.0f * grid) * ::fabsf(reciprocal);
  return AxisPlanes{reciprocal * grid, base - slack, base + slack};
}

// A ray prepared for the compressed tree's box tests: its origin and reciprocal direction, which sides it goes
// towards (octant: bit set where negative, x, y, z), and the order it visits a node's slots in. Slot s lies on the
// + side of axis a where bit a of s is set; the ray meets the side it comes from first, most surely along the axis
// its direction follows most. So a slot's place in the order (0 first) has, for each axis, bit `shift` set where the
// slot is on the far side along that axis, and the axis of the largest |direction| takes the highest bit, the
// smallest the lowest: a ray along x visits all four slots of the near x side first.
struct CompressedRay {
  Vec3<float> origin, inv;
  bool neg_x, neg_y, neg_z;
  u32 octant;
  u32 shift_x, shift_y, shift_z;  // a permutation of 0, 1, 2
};

PT_HD inline CompressedRay make_compressed_ray(const Ray<float>& ray) {
  const Vec3<float> inv = slab_reciprocals(ray);
  const bool neg_x = inv.x < 0.0f, neg_y = inv.y < 0.0f, neg_z = inv.z < 0.0f;
  const float ax = ::fabsf(ray.direction.x), ay = ::fabsf(ray.direction.y), az = ::fabsf(ray.direction.z);
  // Each axis's rank among the three by |direction| (ties broken x < y < z).
  const u32 shift_x = (ax > ay ? 1u : 0u) + (ax > az ? 1u : 0u);
  const u32 shift_y = (ay >= ax ? 1u : 0u) + (ay > az ? 1u : 0u);
  const u32 shift_z = (az >= ax ? 1u : 0u) + (az >= ay ? 1u : 0u);
  return CompressedRay{ray.origin, inv, neg_x, neg_y, neg_z, (neg_x ? 1u : 0u) | (neg_y ? 2u : 0u) | (neg_z ? 4u : 0u), shift_x, shift_y, shift_z};
}

// Slot `slot`'s place in the ray's order of visits, and the slot at a place.
PT_HD inline u32 visit_place(const CompressedRay& r, u32 slot) {
  const u32 far = slot ^ r.octant;
  return (far & 1u) << r.shift_x | (far >> 1 & 1u) << r.shift_y | (far >> 2 & 1u) << r.shift_z;
}
PT_HD inline u32 slot_at_place(const CompressedRay& r, u32 place) {
  return r.octant ^ ((place >> r.shift_x & 1u) | (place >> r.shift_y & 1u) << 1 | (place >> r.shift_z & 1u) << 2);
}

// Tests a node's eight boxes against the ray between t_min and `closest`: the slots entered, leaves and inner nodes
// apart, as masks in the order of visits (bit k for the slot at place k).
PT_HD inline void compressed_box_test(const CompressedBoxes& boxes, const CompressedRay& r, float t_min, float closest, u32& leaves, u32& inner) {
  const AxisPlanes px = axis_planes(boxes.origin[0], boxes.exponent[0], r.origin.x, r.inv.x);
  const AxisPlanes py = axis_planes(boxes.origin[1], boxes.exponent[1], r.origin.y, r.inv.y);
  const AxisPlanes pz = axis_planes(boxes.origin[2], boxes.exponent[2], r.origin.z, r.inv.z);
  leaves = 0;
  inner = 0;
#if defined(__CUDA_ARCH__)
#pragma unroll
#endif
  for (u32 half = 0; half < 2; ++half) {
    // The near plane of an axis is the lo one where the direction is positive. (Chosen by selects: an index
    // that depends on the ray would put the node's words in local memory on a GPU.)
    const u32 lo_x = boxes.planes[0 + half], lo_y = boxes.planes[2 + half], lo_z = boxes.planes[4 + half];
    const u32 hi_x = boxes.planes[6 + half], hi_y = boxes.planes[8 + half], hi_z = boxes.planes[10 + half];
    const u32 near_x = r.neg_x ? hi_x : lo_x, far_x = r.neg_x ? lo_x : hi_x;
    const u32 near_y = r.neg_y ? hi_y : lo_y, far_y = r.neg_y ? lo_y : hi_y;
    const u32 near_z = r.neg_z ? hi_z : lo_z, far_z = r.neg_z ? lo_z : hi_z;
#if defined(__CUDA_ARCH__)
#pragma unroll
#endif
    for (u32 b = 0; b < 4; ++b) {
      const float x0 = fused_multiply_add(plane_byte(near_x, b), px.scale, px.near_base);
      const float x1 = fused_multiply_add(plane_byte(far_x, b), px.scale, px.far_base);
      const float y0 = fused_multiply_add(plane_byte(near_y, b), py.scale, py.near_base);
      const float y1 = fused_multiply_add(plane_byte(far_y, b), py.scale, py.far_base);
      const float z0 = fused_multiply_add(plane_byte(near_z, b), pz.scale, pz.near_base);
      const float z1 = fused_multiply_add(plane_byte(far_z, b), pz.scale, pz.far_base);
      const float near = max(max(x0, y0), max(z0, t_min));
      const float far = min(min(x1, y1), min(z1, closest));
      const u32 slot = 4 * half + b;
      const u32 visit = 1u << visit_place(r, slot);
      if (near <= far) {
        if (boxes.inner_mask & (1u << slot))
          inner |= visit;
        else
          leaves |= visit;
      }
    }
  }
}

// Walks the compressed tree rooted at `root`, calling leaf(first, count, closest) for the leaves the ray enters in
// front of the closest hit so far, as walk_binary does (a leaf sets `closest` below zero to stop the walk). A node's
// eight boxes are tested together; its entered leaves are intersected at once, nearest slot first; the entered inner
// children are visited in the ray's order of slots (CompressedRay), the rest of them kept on the stack as one entry
// (the node and a mask of the places still to visit) and read from the node when their turn comes.
template <class Leaf>
PT_HD inline bool walk_compressed(const CompressedWideNode* nodes, u32 root, const Ray<float>& ray, float& closest, Leaf& leaf) {
  const float t_min = hit_distance_min<float>();
  const CompressedRay r = make_compressed_ray(ray);
  bool found = false;
  u32 stack_node[kBvhMaxDepth + 8], stack_slots[kBvhMaxDepth + 8];
  u32 stack_size = 0;
  u32 node_index = root;
  while (true) {
    u32 leaves, inner;                                      // entered slots, bit k for the slot at place k of the order of visits
    const CompressedBoxes boxes = nodes[node_index].boxes;  // four 16-byte loads
    compressed_box_test(boxes, r, t_min, closest, leaves, inner);
    const CompressedWideNode& node = nodes[node_index];
    while (leaves != 0) {
      const u32 slot = slot_at_place(r, lowest_set_bit(leaves));
      leaves &= leaves - 1u;
      const u32 count = node.count[slot];
      if (count == 0) continue;
      found |= leaf(node.child[slot], count, closest);
      if (closest < 0.0f) return found;
    }
    if (inner != 0) {
      const u32 slot = slot_at_place(r, lowest_set_bit(inner));
      inner &= inner - 1u;
      if (inner != 0) {
        stack_node[stack_size] = node_index;
        stack_slots[stack_size++] = inner;
      }
      node_index = node.child[slot];
      continue;
    }
    if (stack_size == 0) break;
    const u32 parent = stack_node[stack_size - 1];
    u32 rest = stack_slots[stack_size - 1];
    const u32 slot = slot_at_place(r, lowest_set_bit(rest));
    rest &= rest - 1u;
    if (rest == 0)
      --stack_size;
    else
      stack_slots[stack_size - 1] = rest;
    node_index = nodes[parent].child[slot];
  }
  return found;
}

}  // namespace pt
