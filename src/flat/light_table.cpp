// The light table of a flat scene: which primitives emit, how much power each sends out, and the alias table that
// next-event estimation picks lights from in constant time (kernel/lights.hpp).
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "base/scalar_types.hpp"
#include "flat/flat_scene.hpp"
#include "kernel/fixed_point.hpp"

namespace pt {
namespace {

constexpr double kPi = 3.14159265358979323846;
using Vec3d = Vec3<double>;

double luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

template <class T>
double luminance(const Color<T>& c) {
  return luminance(static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z));
}

template <class T>
Vec3d to_double(const Vec3<T>& v) {
  return {static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)};
}

// What a texture shows, for a light's share of power and for the roulette of faint light samples: its mean
// luminance (exact for solid colours and images, the mean of the two colours for checkers; noise, whose mean is near
// its scale of one, counts as one) and its largest channel anywhere (0, not known, for noise). Only the shares and the
// roulette's chances depend on them, never the picture's expected value.
struct TextureBrightness {
  double mean_luminance;
  double brightest;
};

template <class T>
TextureBrightness texture_brightness(const FlatScene<T>& scene, const Texture<T>& texture) {
  auto largest_of = [](double r, double g, double b) { return std::max({r, g, b}); };
  auto of_colour = [&](const Color<T>& c) {
    return TextureBrightness{luminance(c), largest_of(static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z))};
  };
  auto of_pair = [&](const Color<T>& a, const Color<T>& b) {
    return TextureBrightness{0.5 * (luminance(a) + luminance(b)), std::max(of_colour(a).brightest, of_colour(b).brightest)};
  };
  if (const auto* solid = std::get_if<SolidTexture<T>>(&texture)) return of_colour(solid->color);
  if (const auto* checker = std::get_if<CheckerTexture<T>>(&texture)) return of_pair(checker->odd, checker->even);
  if (const auto* checker = std::get_if<UvCheckerTexture<T>>(&texture)) return of_pair(checker->odd, checker->even);
  if (const auto* image = std::get_if<ImageTexture<T>>(&texture)) {
    const std::size_t texels = static_cast<std::size_t>(image->width) * image->height;
    double sum[3] = {0, 0, 0};
    double most = 0;
    for (std::size_t i = 0; i < texels; ++i)
      for (int c = 0; c < 3; ++c) {
        const u8 byte = scene.texels[3 * (image->offset + i) + c];
        sum[c] += scene.srgb_decode[byte];
        most = std::max<double>(most, image->linear ? byte / 255.0 : scene.srgb_decode[byte]);
      }
    const double n = std::max<double>(1, static_cast<double>(texels));
    const Color<T>& f = image->factor;
    return TextureBrightness{
        luminance(sum[0] / n * static_cast<double>(f.x), sum[1] / n * static_cast<double>(f.y), sum[2] / n * static_cast<double>(f.z)),
        most * largest_of(static_cast<double>(f.x), static_cast<double>(f.y), static_cast<double>(f.z))};
  }
  return TextureBrightness{1, 0};
}

// The luminance a material emits (0 for materials that do not).
template <class T>
double emitted_luminance(const FlatScene<T>& scene, u32 material) {
  if (const auto* light = std::get_if<DiffuseLight<T>>(&scene.materials[material]))
    return texture_brightness(scene, scene.textures[light->texture]).mean_luminance;
  return 0;
}

// Walker's alias table (Vose's construction): entry i keeps probability threshold_i of its own and gives the rest
// to its alias, so that each light is picked with probability weight / total.
template <class T>
void fill_alias_table(std::vector<LightEntry<T>>& entries, const std::vector<double>& weights) {
  const std::size_t n = weights.size();
  double total = 0;
  for (double w : weights) total += w;
  std::vector<double> scaled(n);
  std::vector<u32> small, large;
  for (std::size_t i = 0; i < n; ++i) {
    scaled[i] = weights[i] / total * static_cast<double>(n);
    (scaled[i] < 1 ? small : large).push_back(static_cast<u32>(i));
  }
  for (std::size_t i = 0; i < n; ++i) {
    entries[i].pmf = static_cast<T>(weights[i] / total);
    entries[i].alias = static_cast<u32>(i);
    entries[i].threshold = T(1);
  }
  while (!small.empty() && !large.empty()) {
    const u32 s = small.back();
    small.pop_back();
    const u32 l = large.back();
    entries[s].threshold = static_cast<T>(scaled[s]);
    entries[s].alias = l;
    scaled[l] -= 1 - scaled[s];
    if (scaled[l] < 1) {
      large.pop_back();
      small.push_back(l);
    }
  }
  // What is left over (rounding) keeps itself: threshold 1.
}

}  // namespace

template <class T>
void build_light_table(FlatScene<T>& scene, bool with_background) {
  scene.light_entries.clear();
  scene.light_triangle_cdf.clear();
  scene.primitive_light.assign(scene.primitives.size(), kNoLight);
  scene.background_light = kNoLight;
  std::vector<double> powers;
  // One distribution per mesh and material given to the whole mesh (kMeshMaterials: the triangles' own), shared by
  // every instance that places the mesh so.
  std::map<std::pair<u32, u32>, std::pair<u32, double>> mesh_distributions;  // -> first_cdf, emitting area x luminance
  auto mesh_distribution = [&](u32 mesh_index, u32 material) {
    const auto key = std::make_pair(mesh_index, material);
    if (const auto found = mesh_distributions.find(key); found != mesh_distributions.end()) return found->second;
    const MeshRecord& mesh = scene.meshes[mesh_index];
    std::vector<double> cumulative(mesh.triangle_count + 1, 0.0);
    for (u32 i = 0; i < mesh.triangle_count; ++i) {
      const MeshTriangle& tri = scene.mesh_triangles[mesh.first_triangle + i];
      const double emitted = emitted_luminance(scene, material != kMeshMaterials ? material : tri.material);
      double weight = 0;
      if (emitted > 0) {
        const Vec3d a = to_double(scene.mesh_positions[mesh.first_vertex + tri.vertex[0]]);
        const Vec3d b = to_double(scene.mesh_positions[mesh.first_vertex + tri.vertex[1]]);
        const Vec3d c = to_double(scene.mesh_positions[mesh.first_vertex + tri.vertex[2]]);
        weight = emitted * triangle_area(b - a, c - a);
      }
      cumulative[i + 1] = cumulative[i] + weight;
    }
    const double total = cumulative.back();
    std::pair<u32, double> result{kNoLight, total};
    if (total > 0) {
      result.first = static_cast<u32>(scene.light_triangle_cdf.size());
      for (u32 i = 0; i <= mesh.triangle_count; ++i)
        scene.light_triangle_cdf.push_back(static_cast<T>(i == mesh.triangle_count ? 1.0 : cumulative[i] / total));
    }
    mesh_distributions.emplace(key, result);
    return result;
  };

  for (u32 p = 0; p < scene.primitives.size(); ++p) {
    const Primitive<T>& primitive = scene.primitives[p];
    if (std::holds_alternative<ConstantMedium<T>>(primitive.shape)) continue;  // media scatter; they never emit
    double power = 0;
    u32 first_cdf = kNoLight;
    if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
      const auto [first, local_power] = mesh_distribution(instance->mesh, primitive.material);
      if (first == kNoLight) continue;
      first_cdf = first;
      // Areas grow by the map's determinant to the power 2/3 on average (exact for uniform scales): only the share.
      double growth = 1;
      if (instance->transform != kNoTransform) {
        const AffineRows<T>& m = scene.instance_transforms[instance->transform].to_world;
        const double det = std::abs(dot(to_double(m.row[0]), cross(to_double(m.row[1]), to_double(m.row[2]))));
        growth = std::cbrt(det * det);
      }
      power = local_power * growth;
    } else {
      const double emitted = emitted_luminance(scene, primitive.material);
      if (!(emitted > 0)) continue;
      double area = 0;
      if (const auto* s = std::get_if<Sphere<T>>(&primitive.shape))
        area = 4 * kPi * std::pow(static_cast<double>(s->radius), 2);
      else if (const auto* m = std::get_if<MovingSphere<T>>(&primitive.shape))
        area = 4 * kPi * std::pow(static_cast<double>(m->radius), 2);
      else if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
        // In double for fixed point, whose range may not hold the area (a 300 x 265 light in Q16.16).
        if constexpr (is_fixed_v<T>)
          area = quad_area(Quad<double>{to_double(q->corner), to_double(q->normal), to_double(q->du), to_double(q->dv),
                                        static_cast<double>(q->u_extent), static_cast<double>(q->v_extent)});
        else
          area = static_cast<double>(quad_area(*q));
      } else if (const auto* t = std::get_if<Triangle<T>>(&primitive.shape))
        area = triangle_area(to_double(t->edge1), to_double(t->edge2));
      power = emitted * area;
    }
    if (!(power > 0) || !std::isfinite(power)) continue;
    // A mesh's triangles may each have their own material: no one brightness.
    const auto* light = first_cdf == kNoLight ? std::get_if<DiffuseLight<T>>(&scene.materials[primitive.material]) : nullptr;
    const double brightest = light ? texture_brightness(scene, scene.textures[light->texture]).brightest : 0;
    scene.primitive_light[p] = static_cast<u32>(scene.light_entries.size());
    scene.light_entries.push_back(
        LightEntry<T>{p, 0, T(1), T(0), first_cdf, brightest < static_cast<double>(largest<T>()) ? T(brightest) : T(0)});
    powers.push_back(2 * kPi * power);  // both sides emit: pi A L each
  }

  // The background, where it shines, as a light around a sphere that holds the scene (pbrt's measure of a distant
  // light's power: pi R^2 times its mean radiance over the sphere of directions, 4 pi).
  const double background = luminance(background_mean_radiance(scene));
  if (with_background && background > 0) {
    const Vec3d lo = to_double(scene.scene_lo), hi = to_double(scene.scene_hi);
    const double radius = 0.5 * length(hi - lo);
    const double power = std::isfinite(radius) && radius > 0 ? 4 * kPi * kPi * radius * radius * background : background;
    scene.background_light = static_cast<u32>(scene.light_entries.size());
    scene.light_entries.push_back(LightEntry<T>{kNoLight, 0, T(1), T(0), kNoLight, T(0)});  // its own per sample
    powers.push_back(power);
  }
  if (!scene.light_entries.empty()) fill_alias_table(scene.light_entries, powers);
  // Each rectangular light's frame, made here once rather than for every shadow ray (kernel/lights.hpp).
  scene.light_rectangles.assign(scene.light_entries.size(), RectangleFrame<T>{});
  for (std::size_t i = 0; i < scene.light_entries.size(); ++i) {
    const u32 p = scene.light_entries[i].primitive;
    if (p == kNoLight) continue;
    if (const auto* q = std::get_if<Quad<T>>(&scene.primitives[p].shape)) scene.light_rectangles[i] = rectangle_frame(*q);
  }
}

#define PT_INSTANTIATE_LIGHT_TABLE(...) template void build_light_table<__VA_ARGS__>(FlatScene<__VA_ARGS__>&, bool);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_LIGHT_TABLE)

}  // namespace pt
