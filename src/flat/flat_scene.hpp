// The flat scene: the parsed scene turned into arrays of trivially copyable structs in the kernels' scalar type,
// with the BVH built and primitives in BVH order. Backends copy these arrays as they are.
#pragma once

#include <type_traits>
#include <vector>

#include "base/render_settings.hpp"
#include "kernel/integrator.hpp"

namespace pt {

template <class T>
struct FlatScene {
  std::vector<BvhNode<T>> nodes;
  std::vector<WideBvhNode<T>> wide_nodes;  // the same tree, up to kWideBvhWidth children a node (walked on host CPUs: closest_hit)
  Vec3<T> scene_lo{}, scene_hi{};          // the root's box as the binary nodes[0] has it, also where those are not kept
  std::vector<Primitive<T>> primitives;
  std::vector<Primitive<T>> boundaries;
  std::vector<TriangleAttributes<T>> triangle_attributes;
  // Meshes (kernel/shapes.hpp, MeshData): vertex arrays, triangles in BVH order, one record and one BVH per mesh
  // (binary and wide, node indices global), and the transforms of instances.
  std::vector<Vec3<T>> mesh_positions, mesh_normals;
  std::vector<MeshUv<T>> mesh_uvs;
  std::vector<MeshTangent<T>> mesh_tangents;  // only for meshes with vertex tangents whose material has a normal map
  std::vector<MeshTriangle> mesh_triangles;
  std::vector<MeshRecord> meshes;
  std::vector<InstanceTransform<T>> instance_transforms;
  std::vector<BvhNode<T>> mesh_nodes;
  std::vector<WideBvhNode<T>> mesh_wide_nodes;
  std::vector<Material<T>> materials;
  std::vector<Texture<T>> textures;
  std::vector<u8> texels;          // sRGB bytes, three a texel
  std::vector<float> srgb_decode;  // the linear value of each byte
  std::vector<Vec3<T>> perlin_gradients;
  std::vector<u32> perlin_permutations;
  // Lights for next-event estimation (kernel/scene_view.hpp, LightData), built by build_light_table.
  std::vector<LightEntry<T>> light_entries;
  std::vector<RectangleFrame<T>> light_rectangles;  // one per entry
  std::vector<u32> primitive_light;
  std::vector<T> light_triangle_cdf;
  u32 background_light = kNoLight;
  double background_scattering_variance = 0;  // what decided whether the background is a light under auto
  // The environment image, when the background is one (kernel/background.hpp, EnvironmentArrays; empty otherwise):
  // its texels times the strength, and the distribution importance sampling draws directions from.
  std::vector<float> environment_rgb, environment_density, environment_row_cdf, environment_column_cdfs;
  Camera<T> camera;
  Background<T> background;
  RenderParams<T> params;
  u32 samples_per_pixel = 0;
  double noise_threshold = 0;  // adaptive sampling (film/adaptive.hpp); 0: off
  BidirectionalSchedule bidirectional_schedule = BidirectionalSchedule::kAuto;
  double merge_radius = 0;  // vertex merging's first radius (integrator vcm), in the flat scene's lengths
  u32 bvh_depth = 0;
  double bvh_seconds = 0;  // time flatten_scene spent building the BVH (reported by `render --verbose`)
  double scale = 1;        // every length of the scene was multiplied by this to fit the scalar type (docs/numerics.md)

  // Host pointers into the arrays above (the CPU backend renders from this directly).
  SceneView<T> view() const;
  // Bytes of all arrays, as a device copy needs them.
  std::size_t bytes() const;
};

// The background with its environment image's arrays where kernels read them.
template <class T>
Background<T> with_arrays(Background<T> background, const EnvironmentArrays& arrays) {
  background.environment.arrays = arrays;
  return background;
}

// The one list of a flat scene's arrays: `place(array, what)` puts each array where the kernels will read it and
// returns its address there (the host array itself on the CPU, a device copy on a GPU); `what` names it for errors.
// The arrays are placed in the order written here (a braced list is evaluated left to right).
template <class T, class Place>
SceneView<T> place_scene(const FlatScene<T>& scene, Place&& place) {
  return SceneView<T>{
      place(scene.nodes, "copying the BVH"), place(scene.wide_nodes, "copying the wide BVH"),
      nullptr /* the compressed tree: made by a backend that walks it (DeviceBackend::upload) */, place(scene.primitives, "copying the primitives"),
      place(scene.boundaries, "copying the medium boundaries"), place(scene.triangle_attributes, "copying the triangle attributes"),
      MeshData<T>{place(scene.mesh_positions, "copying the mesh vertices"), place(scene.mesh_normals, "copying the mesh normals"),
                  place(scene.mesh_uvs, "copying the mesh texture coordinates"), place(scene.mesh_triangles, "copying the mesh triangles"),
                  place(scene.meshes, "copying the meshes"), place(scene.instance_transforms, "copying the instance transforms"),
                  place(scene.mesh_nodes, "copying the mesh BVHs"), place(scene.mesh_wide_nodes, "copying the mesh BVHs"), nullptr,
                  place(scene.mesh_tangents, "copying the mesh tangents")},
      place(scene.materials, "copying the materials"), place(scene.textures, "copying the textures"),
      // Every image texture's texels in one array; ImageTexture::offset says where each starts.
      TextureData<T>{place(scene.texels, "copying the texels"), place(scene.srgb_decode, "copying the sRGB table"),
                     place(scene.perlin_gradients, "copying the noise tables"), place(scene.perlin_permutations, "copying the noise tables")},
      scene.camera,
      with_arrays(scene.background, EnvironmentArrays{place(scene.environment_rgb, "copying the environment image"),
                                                      place(scene.environment_density, "copying the environment's distribution"),
                                                      place(scene.environment_row_cdf, "copying the environment's distribution"),
                                                      place(scene.environment_column_cdfs, "copying the environment's distribution")}),
      LightData<T>{place(scene.light_entries, "copying the lights"), place(scene.light_rectangles, "copying the lights"),
                   place(scene.primitive_light, "copying the lights"), place(scene.light_triangle_cdf, "copying the lights"),
                   static_cast<u32>(scene.light_entries.size()), scene.background_light},
      scene.params};
}

// Everything kernels read is copied to devices byte for byte.
static_assert(std::is_trivially_copyable_v<Primitive<float>>);
static_assert(std::is_trivially_copyable_v<Material<float>>);
static_assert(std::is_trivially_copyable_v<Texture<float>>);
static_assert(std::is_trivially_copyable_v<BvhNode<float>>);
static_assert(std::is_trivially_copyable_v<WideBvhNode<float>>);
static_assert(std::is_trivially_copyable_v<SceneView<float>>);
static_assert(std::is_trivially_copyable_v<InstanceTransform<float>>);
static_assert(sizeof(MeshTriangle) == 16);
static_assert(sizeof(BvhNode<float>) == 32, "a BVH node fills one 32-byte sector");

// Flattens the scene with the effective render settings (the file's, after command-line overrides), with every
// length multiplied by `scale`; scale 0 picks it: 1 for float and double, for a fixed-point format the largest
// power of two (at most 1) that brings every coordinate within half the square root of the format's range, so
// squared distances fit. Throws InputError when the scene cannot be represented (for instance, too many
// primitives, or a value beyond the type's supported range: docs/scene-format.md, "Supported range of values"),
// naming the file, line:column and JSON path of the value.
struct SceneDescription;  // scene/scene.hpp

template <class T>
FlatScene<T> flatten_scene(const SceneDescription& scene, const RenderSettings& settings, double scale = 0);

// The same, letting go of the scene's objects, materials, textures and image texels as soon as they are converted
// (a large scene's description would otherwise be held beside its flat copy through the BVH's build): `scene` keeps
// its source, settings, camera, background, meshes and warnings.
// `binary_tree`: whether the binary nodes (walked by GPUs) are kept beside the wide ones (walked by host CPUs).
template <class T>
FlatScene<T> flatten_scene_releasing(SceneDescription& scene, const RenderSettings& settings, double scale = 0, bool binary_tree = true);

// The lights of a flat scene whose primitives, materials, meshes and background are in place: every primitive that
// emits (an emitting material with some power), and the background where it is not black and `with_background`, in an
// alias table that picks each by its share of the emitted power (flat/light_table.cpp).
template <class T>
void build_light_table(FlatScene<T>& scene, bool with_background = true);

// How noisily scattering alone finds the background: the relative variance (variance over squared mean) of a diffuse
// surface's irradiance from the background when its directions are drawn by the cosine (as a diffuse material
// scatters), averaged over normals spread evenly over the sphere. 0 for a constant background; about 0.05 for the
// shipped skies' gradients; for a sun of solid angle S it approaches pi / S (thousands). flat/environment.cpp.
template <class T>
double background_scattering_variance(const FlatScene<T>& scene);

// Above this relative variance, light sampling of the background pays for its shadow rays under --light-sampling
// auto: there the cosine's estimate of the background's light is noisier than its own mean, so a second ray that
// draws directions by the background's brightness removes more variance than its cost; below it scattering finds the
// light nearly as well alone (docs/light-transport.md, "Which lights are sampled").
inline constexpr double kBackgroundSamplingVariance = 1.0;
// The background's mean radiance over all directions (the gradient's, or the environment image's as kernels see
// it, strength included), for choosing among lights by power: the power a background sends into a sphere of radius
// r around the scene is pi r^2 times 4 pi times this mean.
template <class T>
Color<double> background_mean_radiance(const FlatScene<T>& scene);

// The brute-force closest hit (every primitive tested): the reference the BVH is checked against.
template <class T>
bool closest_hit_brute_force(const FlatScene<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit);

}  // namespace pt
