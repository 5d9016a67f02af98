// The BVH as kernels see it (a binary tree, and the same tree with levels folded into wide nodes for host CPUs)
// and the closest-hit query over it.
#pragma once

#include <cstddef>
#include <type_traits>

#include "kernel/shapes.hpp"

namespace pt {

template <class T>
struct SceneView;  // kernel/scene_view.hpp: the traversal reads its BVH and primitives

// The compressed wide tree a CUDA build can walk in float (kernel/compressed_bvh.hpp, included by kernel/scene_view.hpp).
struct CompressedWideNode;
template <class Leaf>
PT_HD inline bool walk_compressed(const CompressedWideNode* nodes, u32 root, const Ray<float>& ray, float& closest, Leaf& leaf);

// A node of the flattened BVH. Interior nodes (count == 0) have their first child right after them and the second
// at `left_first`; leaves hold primitives [left_first, left_first + count).
template <class T>
struct BvhNode {
  Vec3<T> lo;
  u32 left_first;
  Vec3<T> hi;
  u32 count;
};

// The builder never makes a deeper tree, so a traversal stack of this size cannot overflow.
inline constexpr u32 kBvhMaxDepth = 64;

// The same tree with levels folded together: a node holds up to eight children's boxes, stored by plane
// (bounds[plane][child], planes lo x, y, z then hi x, y, z) so that one box test covers the children with one
// SIMD lane each on a CPU (eight lanes with AVX, two groups of four with SSE). A child with count 0 is the node
// at `child`; otherwise it is a leaf, primitives [child, child + count). The two masks say which slots hold a leaf
// and which an inner node (bit i for slot i), so that traversal splits the entered children with two ANDs; the
// slots in neither (a node with fewer children) repeat the first child's box and are never entered.
inline constexpr u32 kWideBvhWidth = 8;
template <class T>
struct alignas(32) WideBvhNode {
  T bounds[6][kWideBvhWidth];
  u32 child[kWideBvhWidth];
  u32 count[kWideBvhWidth];
  u32 leaf_mask, inner_mask;
};

// Closest-hit queries count every hit beyond zero: a ray that leaves a surface starts off it already (spawn_ray),
// so no minimum distance is needed against self-intersection.
template <class T>
PT_HD constexpr T hit_distance_min() {
  return T(0);
}

// A ray prepared for slab tests: reciprocal direction, the origin term of the scalar type's slab distance (origin
// times the reciprocal for floating point), and for each axis the byte offset within a BvhNode of the bound the ray
// meets first (lo where the direction is positive, hi where it is negative) and of the one it meets last. Picking
// the planes once per ray saves the min/max pair per axis of every box test, and gives the same entry and exit
// distances: with a fixed reciprocal the rounded plane distance is monotonic in the bound.
template <class T>
struct BoxRay {
  Vec3<T> inv_direction;
  Vec3<T> origin_term;
  u32 near_x, near_y, near_z;
  u32 far_x, far_y, far_z;
};

template <class T>
PT_HD inline T node_bound(const BvhNode<T>& node, u32 byte_offset) {
  return *reinterpret_cast<const T*>(reinterpret_cast<const unsigned char*>(&node) + byte_offset);
}

template <class T>
PT_HD inline T slab_distance(const BvhNode<T>& node, u32 byte_offset, T reciprocal, T origin_term) {
  return ScalarTraits<T>::slab_distance(node_bound(node, byte_offset), reciprocal, origin_term);
}

// Slab test of a node's box against the ray, between t_min and the closest hit so far.
template <class T>
PT_HD inline bool ray_hits_box(const BvhNode<T>& node, const BoxRay<T>& r, T t_min, T t_max, T& t_entry) {
  const T tx0 = slab_distance(node, r.near_x, r.inv_direction.x, r.origin_term.x);
  const T tx1 = slab_distance(node, r.far_x, r.inv_direction.x, r.origin_term.x);
  const T ty0 = slab_distance(node, r.near_y, r.inv_direction.y, r.origin_term.y);
  const T ty1 = slab_distance(node, r.far_y, r.inv_direction.y, r.origin_term.y);
  const T tz0 = slab_distance(node, r.near_z, r.inv_direction.z, r.origin_term.z);
  const T tz1 = slab_distance(node, r.far_z, r.inv_direction.z, r.origin_term.z);
  const T near = max(max(tx0, ty0), max(tz0, t_min));
  const T far = min(min(tx1, ty1), min(tz1, t_max));
  t_entry = near;
  return near <= far;
}

template <class T>
PT_HD inline Vec3<T> slab_reciprocals(const Ray<T>& ray) {
  using Traits = ScalarTraits<T>;
  return Vec3<T>{Traits::slab_reciprocal(ray.direction.x), Traits::slab_reciprocal(ray.direction.y), Traits::slab_reciprocal(ray.direction.z)};
}

template <class T>
PT_HD inline Vec3<T> slab_origin_terms(const Ray<T>& ray, const Vec3<T>& inv) {
  using Traits = ScalarTraits<T>;
  return Vec3<T>{Traits::slab_origin_term(ray.origin.x, inv.x), Traits::slab_origin_term(ray.origin.y, inv.y),
                 Traits::slab_origin_term(ray.origin.z, inv.z)};
}

// The slab-test form of a ray for the binary tree.
template <class T>
PT_HD inline BoxRay<T> make_box_ray(const Ray<T>& ray) {
  const Vec3<T> inv = slab_reciprocals(ray);
  constexpr u32 lo_x = offsetof(BvhNode<T>, lo) + offsetof(Vec3<T>, x), hi_x = offsetof(BvhNode<T>, hi) + offsetof(Vec3<T>, x);
  constexpr u32 lo_y = offsetof(BvhNode<T>, lo) + offsetof(Vec3<T>, y), hi_y = offsetof(BvhNode<T>, hi) + offsetof(Vec3<T>, y);
  constexpr u32 lo_z = offsetof(BvhNode<T>, lo) + offsetof(Vec3<T>, z), hi_z = offsetof(BvhNode<T>, hi) + offsetof(Vec3<T>, z);
  const bool neg_x = inv.x < T(0), neg_y = inv.y < T(0), neg_z = inv.z < T(0);
  return BoxRay<T>{inv,
                   slab_origin_terms(ray, inv),
                   neg_x ? hi_x : lo_x,
                   neg_y ? hi_y : lo_y,
                   neg_z ? hi_z : lo_z,
                   neg_x ? lo_x : hi_x,
                   neg_y ? lo_y : hi_y,
                   neg_z ? lo_z : hi_z};
}

// What a walk of the binary tree tells its caller besides the leaves it enters: before each box test, the node and
// the test's bounds (box_test), and before each node it goes to, whether to go on (keep_walking). The kernel's walks
// take these, which do nothing and compile away; the hardware operand recorder (tests/hardware) records the box
// tests, and the SYCL path probe (tools/sycl) counts the node visits and gives up a walk that does not end.
struct NoWalkHooks {
  template <class T>
  PT_HD void box_test(const BvhNode<T>&, const BoxRay<T>&, T, T) const {}
  PT_HD bool keep_walking() const { return true; }
};

// Walks the binary tree rooted at `root` by iterative traversal with a fixed-size stack, calling
// leaf(first, count, closest) for each leaf the ray enters in front of the closest hit so far; the leaf narrows
// `closest` and returns whether it found a hit, and sets it below zero where the walk can stop (a shadow ray found
// blocked: SceneLeaf). The scene's tree and each mesh's tree are walked by this.
template <class T, class Leaf, class Hooks = NoWalkHooks>
PT_HD inline bool walk_binary(const BvhNode<T>* nodes, u32 root, const BoxRay<T>& box_ray, T& closest, Leaf& leaf, Hooks&& hooks = Hooks{}) {
  const T t_min = hit_distance_min<T>();
  auto hits_box = [&](const BvhNode<T>& node, T& entry) {
    hooks.box_test(node, box_ray, t_min, closest);
    return ray_hits_box(node, box_ray, t_min, closest, entry);
  };
  bool found = false;
  u32 stack[kBvhMaxDepth];
  u32 stack_size = 0;
  u32 node_index = root;
  T entry;
  if (!hits_box(nodes[root], entry)) return false;
  while (hooks.keep_walking()) {
    const BvhNode<T>& node = nodes[node_index];
    if (node.count > 0) {
      found |= leaf(node.left_first, node.count, closest);
      if (closest < T(0)) return found;
    } else {
      u32 near_child = node_index + 1, far_child = node.left_first;
      T near_entry, far_entry;
      const bool near_hit = hits_box(nodes[near_child], near_entry);
      const bool far_hit = hits_box(nodes[far_child], far_entry);
      if (near_hit && far_hit) {
        if (far_entry < near_entry) {
          const u32 swap = near_child;
          near_child = far_child;
          far_child = swap;
        }
        stack[stack_size++] = far_child;
        node_index = near_child;
        continue;
      }
      if (near_hit || far_hit) {
        node_index = near_hit ? near_child : far_child;
        continue;
      }
    }
    if (stack_size == 0) break;
    node_index = stack[--stack_size];
  }
  return found;
}

// For each axis, the row of WideBvhNode::bounds with the plane the ray meets first (lo for a positive direction)
// and the one it meets last.
struct PlaneRows {
  u32 near_x, near_y, near_z, far_x, far_y, far_z;
};

// Entry distances of the ray into the child boxes of a node, and a mask with bit i set where child i is
// entered (unused slots included: the node's masks leave them out).
template <class T>
PT_HD inline u32 wide_box_test(const WideBvhNode<T>& node, const PlaneRows& rows, const Vec3<T>& inv, const Vec3<T>& origin_term, T t_min, T closest,
                               T* entry) {
  using Traits = ScalarTraits<T>;
  u32 entered = 0;
  for (u32 i = 0; i < kWideBvhWidth; ++i) {
    const T x0 = Traits::slab_distance(node.bounds[rows.near_x][i], inv.x, origin_term.x);
    const T x1 = Traits::slab_distance(node.bounds[rows.far_x][i], inv.x, origin_term.x);
    const T y0 = Traits::slab_distance(node.bounds[rows.near_y][i], inv.y, origin_term.y);
    const T y1 = Traits::slab_distance(node.bounds[rows.far_y][i], inv.y, origin_term.y);
    const T z0 = Traits::slab_distance(node.bounds[rows.near_z][i], inv.z, origin_term.z);
    const T z1 = Traits::slab_distance(node.bounds[rows.far_z][i], inv.z, origin_term.z);
    entry[i] = max(max(x0, y0), max(z0, t_min));
    if (entry[i] <= min(min(x1, y1), min(z1, closest))) entered |= 1u << i;
  }
  return entered;
}

#if !defined(__CUDA_ARCH__) && (defined(__GNUC__) || defined(__clang__))
// The same test for float in vector registers (GCC/Clang vector extensions), which GCC 12 does not find by itself
// in the loop above: the children in groups of kBoxTestLanes, eight with AVX, four otherwise (SSE on x86-64, NEON
// on ARM). Same operations in the same order, so the same distances: `a > b ? a : b` is exactly what the scalar
// max does. The mask of entered children comes from one compare per group instead of a branch per child.
#if defined(__AVX__) && !defined(PT_SYCL_KERNELS)
inline constexpr u32 kBoxTestLanes = 8;
#else
inline constexpr u32 kBoxTestLanes = 4;
#endif

// Vectors of 4 and 8 floats, and the masks their comparisons give (a vector size cannot depend on a template
// parameter, hence the specialisations).
template <u32 kLanes>
struct FloatLanes;
template <>
struct FloatLanes<4> {
  typedef float Values __attribute__((vector_size(16)));
  typedef int Mask __attribute__((vector_size(16)));
};
template <>
struct FloatLanes<8> {
  typedef float Values __attribute__((vector_size(32)));
  typedef int Mask __attribute__((vector_size(32)));
};

// The vector test with the children in groups of kLanes, 4 or 8 (both can be built anywhere, so that the tests
// compare them; a group of 8 is one instruction per operation only with AVX). It does not pick the plane rows by
// the ray's direction: it computes both planes of an axis and orders them with a min and a max, which give the
// same two distances (with a fixed reciprocal the rounded plane distance is monotonic in the bound, see BoxRay).
// The six row offsets of a ray were reloaded from the stack at every node (general registers run out in the
// traversal loop); two more vector operations per axis cost less.
template <u32 kLanes>
inline u32 wide_box_test_in_groups(const WideBvhNode<float>& node, const PlaneRows&, const Vec3<float>& inv, const Vec3<float>& origin_term,
                                   float t_min, float closest, float* entry) {
  static_assert(kWideBvhWidth % kLanes == 0);
  using Lanes = typename FloatLanes<kLanes>::Values;
  using Mask = typename FloatLanes<kLanes>::Mask;
  auto vmax = [](Lanes a, Lanes b) { return a > b ? a : b; };
  auto vmin = [](Lanes a, Lanes b) { return a < b ? a : b; };
  const Lanes lower = Lanes{} + t_min, upper = Lanes{} + closest;
  u32 entered = 0;
  for (u32 first = 0; first < kWideBvhWidth; first += kLanes) {
    auto row = [&](u32 r) {
      Lanes v;
      __builtin_memcpy(&v, node.bounds[r] + first, sizeof v);
      return v;
    };
    const Lanes x_lo = row(0) * inv.x - origin_term.x, x_hi = row(3) * inv.x - origin_term.x;
    const Lanes y_lo = row(1) * inv.y - origin_term.y, y_hi = row(4) * inv.y - origin_term.y;
    const Lanes z_lo = row(2) * inv.z - origin_term.z, z_hi = row(5) * inv.z - origin_term.z;
    const Lanes x0 = vmin(x_lo, x_hi), x1 = vmax(x_lo, x_hi);
    const Lanes y0 = vmin(y_lo, y_hi), y1 = vmax(y_lo, y_hi);
    const Lanes z0 = vmin(z_lo, z_hi), z1 = vmax(z_lo, z_hi);
    const Lanes near = vmax(vmax(x0, y0), vmax(z0, lower));
    const Lanes far = vmin(vmin(x1, y1), vmin(z1, upper));
    __builtin_memcpy(entry + first, &near, sizeof near);
    const Mask inside = near <= far;  // all ones where entered
    u32 group = 0;                    // bit i: lane i entered
    // One `if constexpr ... else` chain across the preprocessor's branches, kept as written:
    // clang-format off
#if defined(__AVX__) && !defined(PT_SYCL_KERNELS)
    if constexpr (kLanes == 8) group = static_cast<u32>(__builtin_ia32_movmskps256(reinterpret_cast<Lanes>(inside))); else
#endif
#if defined(__SSE__) && !defined(PT_SYCL_KERNELS)  // SYCL kernels may be compiled for a GPU: no x86 builtins there
    if constexpr (kLanes == 4) group = static_cast<u32>(__builtin_ia32_movmskps(reinterpret_cast<Lanes>(inside))); else
#endif
    for (u32 lane = 0; lane < kLanes; ++lane) group |= static_cast<u32>(inside[lane] & 1) << lane;
    // clang-format on
    entered |= group << first;
  }
  return entered;
}

inline u32 wide_box_test(const WideBvhNode<float>& node, const PlaneRows& rows, const Vec3<float>& inv, const Vec3<float>& origin_term, float t_min,
                         float closest, float* entry) {
  return wide_box_test_in_groups<kBoxTestLanes>(node, rows, inv, origin_term, t_min, closest, entry);
}
#endif

// The box-test form of a ray for the wide tree: reciprocal direction, origin terms, and for each axis the plane row
// it meets first (lo for a positive direction) and last.
template <class T>
struct WideRay {
  Vec3<T> inv, origin_term;
  PlaneRows rows;
};

template <class T>
PT_HD inline WideRay<T> make_wide_ray(const Ray<T>& ray) {
  const Vec3<T> inv = slab_reciprocals(ray);
  return WideRay<T>{inv, slab_origin_terms(ray, inv),
                    PlaneRows{inv.x < T(0) ? 3u : 0u, inv.y < T(0) ? 4u : 1u, inv.z < T(0) ? 5u : 2u, inv.x < T(0) ? 0u : 3u, inv.y < T(0) ? 1u : 4u,
                              inv.z < T(0) ? 2u : 5u}};
}

// Walks the wide tree rooted at `root`, calling leaf(first, count, closest) as walk_binary does. Each node's boxes
// are tested together; leaves among the children are intersected at once (they narrow `closest` before anything is
// pushed), the inner children that were entered in front of the closest hit are visited nearest first, the rest
// pushed. The leaf tests are a branch of their own, away from the loop over inner children: the primitive tests need
// many registers, and with them inside that loop the compiler saved and restored the traversal's state around it at
// every node.
template <class T, class Leaf>
PT_HD inline bool walk_wide(const WideBvhNode<T>* nodes, u32 root, const WideRay<T>& wide_ray, T& closest, Leaf& leaf) {
  const T t_min = hit_distance_min<T>();
  bool found = false;
  u32 stack[kBvhMaxDepth * (kWideBvhWidth - 1)];
  u32 stack_size = 0;
  u32 node_index = root;
  while (true) {
    const WideBvhNode<T>& node = nodes[node_index];
    T entry[kWideBvhWidth];
    const u32 entered = wide_box_test(node, wide_ray.rows, wide_ray.inv, wide_ray.origin_term, t_min, closest, entry);
    u32 leaves = entered & node.leaf_mask;
    u32 inner_mask = entered & node.inner_mask;
    if (leaves != 0) {
      while (leaves != 0) {
        const u32 i = lowest_set_bit(leaves);
        leaves &= leaves - 1u;
        found |= leaf(node.child[i], node.count[i], closest);
        if (closest < T(0)) return found;
      }
      for (u32 rest = inner_mask; rest != 0; rest &= rest - 1u)  // a leaf may have hit something nearer
        if (entry[lowest_set_bit(rest)] > closest) inner_mask &= ~(1u << lowest_set_bit(rest));
    }
    if (inner_mask != 0) {
      const u32 first = lowest_set_bit(inner_mask);
      inner_mask &= inner_mask - 1u;
      if (inner_mask == 0) {  // one inner child entered, the most common case: no sorting
        node_index = node.child[first];
        continue;
      }
      if ((inner_mask & (inner_mask - 1u)) == 0) {  // two: the nearer visited next, the other pushed, without sorting
        const u32 second = lowest_set_bit(inner_mask);
        const bool swap = entry[first] > entry[second];
        stack[stack_size++] = node.child[swap ? first : second];
        node_index = node.child[swap ? second : first];
        continue;
      }
      // More: sorted by entry distance (insertion sort), the nearest visited next, the others pushed.
      u32 inner[kWideBvhWidth];
      T inner_entry[kWideBvhWidth];
      inner[0] = node.child[first];
      inner_entry[0] = entry[first];
      u32 inner_count = 1;
      while (inner_mask != 0) {
        const u32 i = lowest_set_bit(inner_mask);
        inner_mask &= inner_mask - 1u;
        u32 at = inner_count++;
        while (at > 0 && inner_entry[at - 1] > entry[i]) {
          inner[at] = inner[at - 1];
          inner_entry[at] = inner_entry[at - 1];
          --at;
        }
        inner[at] = node.child[i];
        inner_entry[at] = entry[i];
      }
      for (u32 k = inner_count - 1; k > 0; --k) stack[stack_size++] = inner[k];
      node_index = inner[0];
      continue;
    }
    if (stack_size == 0) break;
    node_index = stack[--stack_size];
  }
  return found;
}

// GPU threads are the SIMD lanes already, and a wide node would lengthen each thread's serial work, so GPUs walk the
// binary tree; host CPUs the wide one in floating point, testing a node's boxes at once. Under AdaptiveCpp's
// single-pass compiler one source serves both: the choice is a branch that its run-time compiler folds for the target
// at hand. A CUDA build with PT_CUDA_COMPRESSED_BVH walks the compressed wide tree in float instead
// (kernel/compressed_bvh.hpp; slower on an H200 as it stands: BENCHMARKS.md, "A compressed wide BVH on the GPU"),
// which shares the wide tree's indices.
template <class T, class Leaf>
PT_HD inline bool walk_tree(const BvhNode<T>* nodes, const WideBvhNode<T>* wide_nodes, const CompressedWideNode* compressed_nodes, u32 root,
                            u32 wide_root, const Ray<T>& ray, T& closest, Leaf& leaf) {
  (void)compressed_nodes;
#if defined(__CUDA_ARCH__)
  (void)wide_nodes;
#if defined(PT_CUDA_COMPRESSED_BVH)
  if constexpr (std::is_same_v<T, float>) return walk_compressed(compressed_nodes, wide_root, ray, closest, leaf);
#endif
  return walk_binary(nodes, root, make_box_ray(ray), closest, leaf);
#elif defined(PT_ACPP_SINGLE_PASS)
  __acpp_if_target_device(return walk_binary(nodes, root, make_box_ray(ray), closest, leaf);) return walk_wide(wide_nodes, wide_root,
                                                                                                               make_wide_ray(ray), closest, leaf);
#else
  // Fixed point walks the binary tree here too: it is the datapath a hardware engine implements (the rtl backend),
  // and the order of a walk decides between hits at equal distances, so the host walks it as the engine does.
  if constexpr (!std::is_floating_point_v<T>) return walk_binary(nodes, root, make_box_ray(ray), closest, leaf);
  (void)nodes;
  (void)root;
  // A view given the compressed trees on the host walks them (the tests check that tree against brute force so).
  if constexpr (std::is_same_v<T, float>)
    if (compressed_nodes != nullptr) return walk_compressed(compressed_nodes, wide_root, ray, closest, leaf);
  return walk_wide(wide_nodes, wide_root, make_wide_ray(ray), closest, leaf);
#endif
}

// The triangles of a mesh leaf, in the mesh's space. A hit nearer than `blocked_before` (a shadow ray's, where the
// mesh is not the light it aims at) sets `closest` below zero: the walk stops there.
template <class T>
struct MeshLeaf {
  const MeshData<T>& meshes;
  u32 first_vertex;
  const Ray<T>& ray;  // in the mesh's space
  Hit<T>& hit;
  T blocked_before;
  PT_HD bool operator()(u32 first, u32 count, T& closest) const {
    bool found = false;
    for (u32 i = first; i < first + count; ++i) {
      const MeshTriangle& tri = meshes.triangles[i];
      const Vec3<T>& p0 = meshes.positions[first_vertex + tri.vertex[0]];
      const Triangle<T> triangle{p0, meshes.positions[first_vertex + tri.vertex[1]] - p0, meshes.positions[first_vertex + tri.vertex[2]] - p0, -1};
      Hit<T> candidate;
      if (intersect_triangle(triangle, ray, hit_distance_min<T>(), closest, candidate)) {
        closest = candidate.t;
        hit.t = candidate.t;
        hit.b1 = candidate.b1;
        hit.b2 = candidate.b2;
        hit.triangle = i;
        found = true;
        if (candidate.t < blocked_before) {
          closest = T(-1);
          return true;
        }
      }
    }
    return found;
  }
};

// A world ray taken into an instance's mesh space. Its direction is not renormalised, so distances along it stay
// those of the world ray and hits on different instances compare by t.
template <class T>
PT_HD inline Ray<T> instance_ray(const MeshData<T>& meshes, const MeshInstance<T>& instance, const Ray<T>& ray) {
  Ray<T> local = ray;
  if (instance.transform != kNoTransform) {
    const AffineRows<T>& to_mesh = meshes.transforms[instance.transform].to_mesh;
    local.origin = to_mesh.point(ray.origin);
    local.direction = to_mesh.vector(ray.direction);
  }
  return local;
}

// A mesh instance: the ray taken into the mesh's space and the mesh's own tree walked (stopping at a hit nearer than
// `blocked_before`, which leaves `closest` below zero).
template <class T>
PT_HD inline bool intersect_instance(const MeshData<T>& meshes, const MeshInstance<T>& instance, const Ray<T>& ray, T& closest, Hit<T>& hit,
                                     T blocked_before = T(0)) {
  const Ray<T> local = instance_ray(meshes, instance, ray);
  const MeshRecord& mesh = meshes.meshes[instance.mesh];
  MeshLeaf<T> leaf{meshes, mesh.first_vertex, local, hit, blocked_before};
  return walk_tree(meshes.nodes, meshes.wide_nodes, meshes.compressed_nodes, mesh.root, mesh.wide_root, local, closest, leaf);
}

// The primitives of a leaf of the scene's tree. A hit that blocks a shadow ray (IntersectContext::blocked_before)
// sets `closest` below zero: the walk stops, with that hit.
template <class T>
struct SceneLeaf {
  const SceneView<T>& scene;
  const Ray<T>& ray;
  const IntersectContext<T>& context;
  Hit<T>& hit;
  // How near a hit on `primitive` must be to block the ray: 0 (never) for the light it aims at and for other rays.
  PT_HD T blocked_before(u32 primitive) const { return primitive != context.light_primitive ? context.blocked_before : T(0); }
  PT_HD bool blocks(u32 primitive) const { return hit.t < blocked_before(primitive); }
  PT_HD bool operator()(u32 first, u32 count, T& closest) const {
    bool found = false;
    for (u32 i = first; i < first + count; ++i) {
      const Primitive<T>& primitive = scene.primitives[i];
      if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
        if (intersect_instance(scene.meshes, *instance, ray, closest, hit, blocked_before(i))) {
          hit.primitive = i;
          found = true;
          if (blocks(i)) {
            closest = T(-1);
            return true;
          }
        }
        continue;
      }
      Hit<T> candidate;
      if (intersect_primitive(primitive, i, context, ray, hit_distance_min<T>(), closest, candidate)) {
        closest = candidate.t;
        hit = candidate;
        hit.primitive = i;
        found = true;
        if (blocks(i)) {
          closest = T(-1);
          return true;
        }
      }
    }
    return found;
  }
};

// Closest hit along the ray (beyond zero) over the binary tree; `hooks` see the walk of the scene's tree.
template <class T, class Hooks = NoWalkHooks>
PT_HD inline bool closest_hit_binary(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit,
                                     T t_max = largest<T>(), Hooks&& hooks = Hooks{}) {
  T closest = t_max;
  SceneLeaf<T> leaf{scene, ray, context, hit};
  return walk_binary(scene.nodes, 0u, make_box_ray(ray), closest, leaf, hooks);
}

// Closest hit along the ray (beyond zero) over the wide tree.
template <class T>
PT_HD inline bool closest_hit_wide(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit,
                                   T t_max = largest<T>()) {
  T closest = t_max;
  SceneLeaf<T> leaf{scene, ray, context, hit};
  return walk_wide(scene.wide_nodes, 0u, make_wide_ray(ray), closest, leaf);
}

// Closest hit along the ray (beyond zero) over the compressed wide tree (float only; SceneView::compressed_nodes set).
template <class T>
PT_HD inline bool closest_hit_compressed(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit,
                                         T t_max = largest<T>()) {
  T closest = t_max;
  SceneLeaf<T> leaf{scene, ray, context, hit};
  return walk_compressed(scene.compressed_nodes, 0u, ray, closest, leaf);
}

// Closest hit along the ray (beyond zero, before t_max), over the tree the device walks best (walk_tree).
template <class T>
PT_HD inline bool closest_hit(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit, T t_max = largest<T>()) {
#if defined(__CUDA_ARCH__)
#if defined(PT_CUDA_COMPRESSED_BVH)
  if constexpr (std::is_same_v<T, float>) return closest_hit_compressed(scene, ray, context, hit, t_max);
#endif
  return closest_hit_binary(scene, ray, context, hit, t_max);
#elif defined(PT_ACPP_SINGLE_PASS)
  __acpp_if_target_device(return closest_hit_binary(scene, ray, context, hit, t_max);) return closest_hit_wide(scene, ray, context, hit, t_max);
#else
  if constexpr (!std::is_floating_point_v<T>) return closest_hit_binary(scene, ray, context, hit, t_max);  // see walk_tree
  return closest_hit_wide(scene, ray, context, hit, t_max);
#endif
}

}  // namespace pt
