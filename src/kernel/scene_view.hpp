// The flat scene as kernels see it: plain pointers to arrays of trivially copyable structs (device pointers on
// an accelerator), the camera, the background and the render's parameters.
#pragma once

#include "kernel/background.hpp"
#include "kernel/bvh.hpp"
#include "kernel/camera.hpp"

namespace pt {

template <class T>
struct RenderParams {
  u32 width, height;
  u32 max_depth;
  u32 seed;
  u32 roulette_depth;  // 0: no Russian roulette
};

template <class T>
struct SceneView {
  const BvhNode<T>* nodes;
  const WideBvhNode<T>* wide_nodes;
  const Primitive<T>* primitives;
  const Primitive<T>* boundaries;
  const TriangleAttributes<T>* triangle_attributes;
  MeshData<T> meshes;
  const Material<T>* materials;
  const Texture<T>* textures;
  TextureData<T> texture_data;
  Camera<T> camera;
  Background<T> background;  // with its environment image's arrays, when it has one
  RenderParams<T> params;
};

}  // namespace pt
