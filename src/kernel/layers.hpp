// Render layers: what the first thing each camera sample meets looks like (its albedo, shading normal and
// distance), the guides a denoiser takes beside the image. A sample's camera ray, and the first hit of a ray
// entering a medium, are the image's own (the same random numbers), so the layers describe the image's samples.
#pragma once

#include "kernel/integrator.hpp"

namespace pt {

// Sums over a pixel's layer samples, as FilmPixel sums its radiance: albedo and normal over every sample (one that
// leaves the scene adds the background's radiance clamped to [0, 1] as its albedo, and no normal), the distance
// over those that hit something.
struct LayerPixel {
  double albedo[3];
  double normal[3];
  double depth;
  u32 hits;
  u32 samples;
};

// The colour a surface gives the light it scatters, without lighting: what a denoiser calls albedo. A texture's
// value where the material has one, a metal's albedo, glass's tint, a light's emission clamped to [0, 1] (a light
// is as bright as its albedo allows), glTF's base colour.
template <class T>
PT_HD inline Color<T> material_albedo(const Material<T>& material, const SurfacePoint<T>& at, const Texture<T>* textures,
                                      const TextureData<T>& data) {
  struct Albedo {
    const SurfacePoint<T>& at;
    const Texture<T>* textures;
    const TextureData<T>& data;
    PT_HD Color<T> texture(u32 index) const { return texture_value(textures[index], TexturePoint<T>{at.u, at.v, at.p}, data); }
    PT_HD Color<T> operator()(const Lambertian<T>& m) const { return texture(m.texture); }
    PT_HD Color<T> operator()(const Metal<T>& m) const { return m.albedo; }
    PT_HD Color<T> operator()(const Dielectric<T>& m) const { return m.tint; }
    PT_HD Color<T> operator()(const DiffuseLight<T>& m) const {
      const Color<T> e = texture(m.texture);
      return Color<T>{clamp(e.x, T(0), T(1)), clamp(e.y, T(0), T(1)), clamp(e.z, T(0), T(1))};
    }
    PT_HD Color<T> operator()(const Isotropic<T>& m) const { return texture(m.texture); }
    PT_HD Color<T> operator()(const MetallicRoughness<T>& m) const { return texture(m.base_color); }
  };
  return visit(Albedo{at, textures, data}, material);
}

// The normal a denoiser sees at a hit: the shading normal facing the camera, bent by a normal map where the
// material has one (as scattering bends it).
template <class T>
PT_HD inline Vec3<T> layer_normal(const Material<T>& material, const SurfacePoint<T>& at, const Vec3<T>& wo, const Texture<T>* textures,
                                  const TextureData<T>& data) {
  if (const auto* m = std::get_if<MetallicRoughness<T>>(&material)) return metallic_roughness_normal(*m, at, wo, textures, data);
  return at.normal;
}

// Adds the layers of sample `sample` of pixel (x, y) to `pixel`. Samples are added in increasing order, so the sums
// do not depend on how the pass is split.
template <class T>
PT_HD inline void add_layer_sample(const SceneView<T>& scene, u32 x, u32 y, u32 s, LayerPixel& pixel) {
  LayerPixel sum = pixel;
  {
    const SampleRandom random = path_random(scene.params, y * scene.params.width + x, s);
    const Ray<T> ray = start_path(scene, x, y, random).ray;
    Hit<T> hit{};
    Color<T> albedo;
    Vec3<T> normal{};
    ++sum.samples;
    if (closest_hit(scene, ray, IntersectContext<T>{scene.boundaries, &random, 0}, hit)) {
      const Primitive<T>& primitive = scene.primitives[hit.primitive];
      const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
      const SurfacePoint<T> at = describe_hit(primitive, scene.triangle_attributes, scene.meshes, ray, hit,
                                              material_needs_uv(material, scene.textures), material_needs_tangent(material));
      albedo = material_albedo(material, at, scene.textures, scene.texture_data);
      normal = layer_normal(material, at, -normalize(ray.direction), scene.textures, scene.texture_data);
      const double depth = static_cast<double>(hit.t) * static_cast<double>(length(ray.direction));
      if (is_finite(albedo) && is_finite(normal) && depth == depth) {
        sum.depth += depth;
        ++sum.hits;
      } else {
        albedo = Color<T>{};
        normal = Vec3<T>{};
      }
    } else {
      const Color<T> b = background_radiance(scene.background, normalize(ray.direction));
      albedo = Color<T>{clamp(b.x, T(0), T(1)), clamp(b.y, T(0), T(1)), clamp(b.z, T(0), T(1))};
      if (!is_finite(albedo)) albedo = Color<T>{};
    }
    sum.albedo[0] += static_cast<double>(albedo.x);
    sum.albedo[1] += static_cast<double>(albedo.y);
    sum.albedo[2] += static_cast<double>(albedo.z);
    sum.normal[0] += static_cast<double>(normal.x);
    sum.normal[1] += static_cast<double>(normal.y);
    sum.normal[2] += static_cast<double>(normal.z);
  }
  pixel = sum;
}

// The layers of one sample of every pixel of a band of the image's rows (a whole image is the band from row 0):
// one sample a launch on every device, with no loop over samples around the BVH walk (which GPU compilers have
// got wrong: MegakernelSample in kernel/integrator.hpp).
template <class T>
struct LayersSample {
  SceneView<T> scene;
  LayerPixel* layers;
  u32 sample;
  u32 first_row = 0;
  PT_HD void operator()(u32 x, u32 y) const {
    add_layer_sample(scene, x, first_row + y, sample, layers[static_cast<std::size_t>(y) * scene.params.width + x]);
  }
};

}  // namespace pt
