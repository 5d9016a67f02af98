// The flat scene as kernels see it: plain pointers to arrays of trivially copyable structs (device pointers on
// an accelerator), the camera, the background and the render's parameters.
#pragma once

#include "kernel/background.hpp"
#include "kernel/bvh.hpp"
#include "kernel/compressed_bvh.hpp"
#include "kernel/camera.hpp"

namespace pt {

// One pass of vertex merging (VCM): camera vertices take the light vertices of the pass's light subpaths that lie within
// `radius` as their own (a density estimate over the disc of that radius). eta = pi radius^2 light_subpaths relates the
// densities of merging and joining at one vertex; the weights need its power and its inverse's.
template <class T>
struct MergeParams {
  T radius;           // 0: no merging
  T merge_share;      // mis_power(eta): merging at a vertex over joining there
  T connect_share;    // mis_power(1 / eta)
  T normalization;    // 1 / eta
};

template <class T>
struct RenderParams {
  u32 width, height;
  u32 max_depth;
  u32 seed;
  u32 roulette_depth;   // 0: no Russian roulette
  u32 next_event;       // 1: next-event estimation with multiple importance sampling (kernel/lights.hpp); 0: none
  SamplerKind sampler;  // how each pixel's samples are placed (kernel/random.hpp)
  T light_threshold;    // shadow rays that could add less are traced by chance (kernel/integrator.hpp); 0: all
  // Bidirectional path tracing's unit of length in fixed point (a power of two; kernel/bidirectional.hpp, "The
  // weights' unit of length"); 1 in floating point.
  T bidirectional_unit = T(1);
  // Vertex merging's pass (kernel/bidirectional.hpp, "Vertex merging"); all zero where light vertices are only joined.
  MergeParams<T> merging{};
};

// ---- Lights, for next-event estimation ----
inline constexpr u32 kNoLight = 0xffffffffu;

// One light of the alias table that picks lights by power: entry i is taken with probability threshold, else its
// alias. `pmf` is the probability that the light is picked in all. The background is the entry whose primitive is
// kNoLight. An emitting mesh instance picks a triangle by the distribution that starts at `first_cdf`.
template <class T>
struct LightEntry {
  u32 primitive;
  u32 alias;
  T threshold;
  T pmf;
  u32 first_cdf;  // kNoLight but for mesh instances
  T brightest;    // the largest channel of radiance the light emits anywhere; 0 where not known (and the background's)
};

// A rectangular light's frame, the same from wherever the light is seen, so made once (build_light_table) rather
// than for every shadow ray: unit vectors x and y along its edges, z = x cross y, and the edges' lengths; lu = 0
// where the light is no rectangle (kernel/lights.hpp, rectangle_frame).
template <class T>
struct RectangleFrame {
  Vec3<T> x, y, z;
  T lu, lv;
};

template <class T>
struct LightData {
  const LightEntry<T>* entries;
  const RectangleFrame<T>* rectangles;  // per entry: the frame of a rectangular light (lu = 0 for other lights)
  const u32* primitive_light;           // per primitive: its entry, or kNoLight where it does not emit
  const T* triangle_cdf;                // per emitting mesh (and material it is given), triangle_count + 1 values from 0 to 1
  u32 count;
  u32 background;  // the background's entry, or kNoLight where it is black
};

template <class T>
struct SceneView {
  const BvhNode<T>* nodes;
  const WideBvhNode<T>* wide_nodes;
  const CompressedWideNode* compressed_nodes;  // the wide nodes compressed where a backend walks them, else null (kernel/bvh.hpp, walk_tree)
  const Primitive<T>* primitives;
  const Primitive<T>* boundaries;
  const TriangleAttributes<T>* triangle_attributes;
  MeshData<T> meshes;
  const Material<T>* materials;
  const Texture<T>* textures;
  TextureData<T> texture_data;
  Camera<T> camera;
  Background<T> background;  // with its environment image's arrays, when it has one
  LightData<T> lights;
  RenderParams<T> params;
};

}  // namespace pt
