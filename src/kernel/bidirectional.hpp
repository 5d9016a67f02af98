// Bidirectional path tracing (Veach 1997): one camera sample of a pixel joined with one light subpath at every pair of
// vertices, the strategies combined by the power heuristic. The weights are formed as the subpaths grow (the recursive
// form of Georgiev et al., "Light Transport Simulation with Vertex Connection and Merging", 2012, and its technical
// report), so that only the light subpath's vertices are stored and the camera subpath needs a few numbers a vertex.
// Paths whose light is the background are found by the camera subpath only (escaping, or a shadow ray towards it),
// weighted as the path tracer weighs them. docs/light-transport.md derives the estimator and states its limits.
#pragma once

#include <new>
#include <type_traits>

#include "kernel/integrator.hpp"

namespace pt {

// Light subpaths draw their random numbers at bounces from here on, apart from the camera subpath's.
inline constexpr u32 kLightPathBounce = 1u << 16;

// Light subpath vertices a sample keeps: one a bounce but the last (a path of at most kMaxBidirectionalDepth segments
// joins a light vertex to a camera vertex that is not the camera). Renders take at most this depth (the host checks).
inline constexpr u32 kMaxBidirectionalDepth = 50;
inline constexpr u32 kMaxLightVertices = kMaxBidirectionalDepth - 2;

// Random dimensions of a light subpath's start (at bounce kLightPathBounce; the point on the light takes
// kDimLightPoint and kDimLightTriangle, as light sampling does) and of a lens point for light tracing.
enum BidirectionalDimension : u32 {
  kDimEmissionDirection = 30,  // pair: the direction about the light's normal
  kDimEmissionSide = 32,       // which side of a two-sided light
};

// The power heuristic's exponent applied to a ratio of densities.
template <class T>
PT_HD inline T mis_power(T x) {
  return x * x;
}

// mis_power(x) y, formed in fixed point as x (x y): a ratio x whose square lies beyond the format's range (a vertex near
// the camera, a light sample of small density) can still meet a running quantity y that brings the product back.
template <class T>
PT_HD inline T mis_power_times(T x, T y) {
  if constexpr (!std::is_floating_point_v<T>)
    return x * (x * y);
  else
    return mis_power(x) * y;
}

// ---- The weights' unit of length ----
// The weights' running quantities (d_VCM and d_VC below) are squared areas, and a light subpath's throughput carries
// the light's area: floating point holds them at any scene's size, fixed point does not (the Cornell box's light has
// an area of 13,650, the square of that is far beyond Q32.32's range). In fixed point bidirectional path tracing forms
// them in a unit of length of its own, RenderParams::bidirectional_unit, a power of two chosen when flattening so that
// the camera stands about one unit from what it looks at: distances are multiplied by it before they are squared and
// densities per area are formed from lengths in it. Every contribution is a ratio in which the unit cancels. The
// geometry keeps its own scale (shrinking it instead costs the intersection tests their precision). Floating point
// keeps its arithmetic.
template <class T>
PT_HD inline T to_unit(const SceneView<T>& scene, T length) {
  if constexpr (!std::is_floating_point_v<T>)
    return length * scene.params.bidirectional_unit;
  else
    return length;
}

template <class T>
PT_HD inline Vec3<T> to_unit(const SceneView<T>& scene, const Vec3<T>& v) {
  if constexpr (!std::is_floating_point_v<T>)
    return v * scene.params.bidirectional_unit;
  else
    return v;
}

// A vector's squared length in the unit.
template <class T>
PT_HD inline T unit_distance_squared(const SceneView<T>& scene, const Vec3<T>& offset) {
  return length_squared(to_unit(scene, offset));
}

// The direction of `offset`, whose squared length in the unit is `distance2`.
template <class T>
PT_HD inline Vec3<T> unit_direction(const Vec3<T>& offset, T distance2) {
  if constexpr (!std::is_floating_point_v<T>)
    return normalize(offset);
  else
    return offset / sqrt(distance2);
}

// The kernel's calls of the BVH walk, the hit description and the material evaluation, each out of line (PT_NOINLINE).
template <class T>
PT_NOINLINE PT_HD bool bidirectional_hit(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit, T t_max) {
  return closest_hit(scene, ray, context, hit, t_max);
}

template <class T>
PT_NOINLINE PT_HD SurfacePoint<T> bidirectional_describe(const SceneView<T>& scene, const Ray<T>& ray, const Hit<T>& hit, const Material<T>& material,
                                                          bool needs_tangent) {
  return describe_hit(scene.primitives[hit.primitive], scene.triangle_attributes, scene.meshes, ray, hit, material_needs_uv(material, scene.textures),
                      needs_tangent && material_needs_tangent(material));
}

template <class T>
PT_NOINLINE PT_HD ScatterValue<T> bidirectional_evaluate(const SceneView<T>& scene, const Material<T>& material, const SurfacePoint<T>& at, const Vec3<T>& wo,
                                                         const Vec3<T>& wi) {
  return material_evaluate(material, at, wo, wi, scene.textures, scene.texture_data);
}

// A light subpath vertex where a connection can be made (a material light sampling serves: diffuse, glossy, a medium).
// `throughput` is the light's emission times the subpath's scattering over its densities, up to the vertex (the cosine
// at the vertex towards the previous one left out, as the path tracer's throughput leaves it out);
// `reverse_mis`, `connect_mis` and `merge_mis` are the running quantities of the weights (d_VCM, d_VC and d_VM of the
// report; merge_mis only in a merging pass).
template <class T>
struct LightVertex {
  SurfacePoint<T> at;
  Color<T> throughput;
  Vec3<T> toward_light;  // unit, back along the subpath
  T reverse_mis, connect_mis, merge_mis;
  u32 primitive, triangle;
  u32 segments;  // of the light subpath up to here
  bool in_medium;
};

// Room for a light subpath's vertices, left uninitialised: each is written whole before it is read, and clearing all of
// them at every sample took 5 % of the CPU's time. A LightVertex is an aggregate, hence of implicit-lifetime type, so
// the bytes' storage holds the array of them that the subpath's writes need (C++20 [intro.object]).
template <class T>
struct LightVertexStore {
  static_assert(std::is_aggregate_v<LightVertex<T>> && std::is_trivially_destructible_v<LightVertex<T>> &&
                std::is_trivially_copy_assignable_v<LightVertex<T>>);
  alignas(LightVertex<T>) unsigned char bytes[sizeof(LightVertex<T>) * kMaxLightVertices];
  PT_HD LightVertex<T>* vertices() { return std::launder(reinterpret_cast<LightVertex<T>*>(bytes)); }
};

// Vertices of one sample in an array shared with other samples: vertex i at first[i * stride]. The one-kernel schedule
// keeps a sample's light vertices side by side (stride 1); the staged one keeps vertex i of every pixel of a band side by
// side, so that neighbouring threads read neighbouring memory.
template <class V>
struct Strided {
  V* first;
  u32 stride;
  PT_HD V& operator[](u32 i) const { return first[static_cast<std::size_t>(i) * stride]; }
  // The same vertices, read only (what the connections take).
  // (A template, so that Strided<const V> has no conversion to itself, which nvcc warns of.)
  template <class U>
    requires(std::is_same_v<U, V> && !std::is_const_v<U>)
  PT_HD operator Strided<const U>() const {
    return {first, stride};
  }
};

// A camera subpath vertex where connections to light vertices are made (a material light sampling serves), with what
// the connections need: the path's throughput up to it, the direction back towards the camera and the running
// quantities of the weights.
template <class T>
struct CameraVertex {
  SurfacePoint<T> at;
  Color<T> throughput;
  Vec3<T> toward_camera;  // unit, back along the subpath
  T reverse_mis, connect_mis, merge_mis;
  T time;
  u32 segments;  // of the camera subpath up to here
  bool in_medium;
};

// |cos| of a direction with a vertex's surface, 1 in a medium (no surface: densities per volume need no cosine).
template <class T>
PT_HD inline T vertex_cosine(const SurfacePoint<T>& at, bool in_medium, const Vec3<T>& direction) {
  return in_medium ? T(1) : abs(dot(at.geometric_normal, direction));
}

// Whether a hit is a scattering point inside a medium rather than on a surface.
template <class T>
PT_HD inline bool hit_in_medium(const SceneView<T>& scene, const Hit<T>& hit) {
  return std::holds_alternative<ConstantMedium<T>>(scene.primitives[hit.primitive].shape);
}

// ---- Vertex merging's place in the weights ----
// In a merging pass (RenderParams::merging) every surface vertex light sampling serves is also where a camera subpath
// can take a light subpath's vertex nearby as its own: one more strategy there, whose density relative to joining at
// that vertex is eta (MergeParams). Vertices in a medium are not merged (their densities are per volume), so merging
// has no share there. Outside a merging pass the shares are zero and the weights are bidirectional path tracing's,
// operation for operation (adding a zero share changes no value).
template <class T>
PT_HD inline bool merging(const SceneView<T>& scene) {
  return scene.params.merging.radius > T(0);
}

template <class T>
PT_HD inline T merge_share_at(const SceneView<T>& scene, bool in_medium) {
  return in_medium ? T(0) : scene.params.merging.merge_share;
}

// The running quantities of a subpath's weights after it scatters from a vertex light sampling serves into a direction
// of density `pdf` at cosine `out_cosine`, the reverse direction having density `reverse_pdf` (Georgiev et al.'s
// report, with merging's terms where a merging pass makes them). Both subpaths update them here.
template <class T>
PT_HD inline void weights_after_scattering(const SceneView<T>& scene, bool in_medium, T out_cosine, T pdf, T reverse_pdf, T& reverse_mis, T& connect_mis,
                                           T& merge_mis) {
  const T out_share = mis_power(out_cosine / pdf), reverse = mis_power(reverse_pdf);
  if (merging(scene))
    merge_mis = out_share * (merge_mis * reverse + reverse_mis * scene.params.merging.connect_share + (in_medium ? T(0) : T(1)));
  connect_mis = out_share * (connect_mis * reverse + reverse_mis + merge_share_at(scene, in_medium));
  reverse_mis = mis_power(T(1) / pdf);
}

// The same after a specular choice (mirror, glass, fuzzy metal): no strategy ends at such a vertex.
template <class T>
PT_HD inline void weights_after_specular(const SceneView<T>& scene, T out_cosine, T& reverse_mis, T& connect_mis, T& merge_mis) {
  reverse_mis = T(0);
  connect_mis *= mis_power(out_cosine);
  if (merging(scene)) merge_mis *= mis_power(out_cosine);
}

// ---- The camera seen from the scene ----
// Where a direction from a point of the lens crosses the image, and the density per unit solid angle with which
// camera rays of the whole image take it: the image is sampled uniformly on the focus plane (area A at distance D along
// the axis), so the density is D^2 / (cos^3 A) with cos the angle to the axis. Light tracing weighs its splats by it
// (the pixel sums are divided by samples per pixel, and there are as many light subpaths as camera samples).
template <class T>
struct CameraImportance {
  T density;  // 0: the direction misses the image
  u32 x, y;
};

// Lengths are taken in the weights' unit (the ratios do not depend on it): the image's area is a square of lengths.
template <class T>
PT_HD inline CameraImportance<T> camera_importance(const SceneView<T>& scene, const Vec3<T>& lens_point, const Vec3<T>& direction) {
  const Camera<T>& camera = scene.camera;
  const u32 width = scene.params.width, height = scene.params.height;
  CameraImportance<T> out{T(0), 0, 0};
  const Vec3<T> lower_left = to_unit(scene, camera.lower_left), horizontal = to_unit(scene, camera.horizontal), vertical = to_unit(scene, camera.vertical);
  const Vec3<T> axis = lower_left + constant<T>(0.5) * horizontal + constant<T>(0.5) * vertical - to_unit(scene, camera.origin);
  const T focus = length(axis);
  const T cosine = dot(direction, axis) / focus;
  if (!(cosine > T(0))) return out;
  const Vec3<T> on_plane = to_unit(scene, lens_point) + direction * (focus / cosine) - lower_left;
  const T s = dot(on_plane, horizontal) / length_squared(horizontal);
  const T t = dot(on_plane, vertical) / length_squared(vertical);
  if (!(s >= T(0) && s < T(1) && t > T(0) && t <= T(1))) return out;
  const u32 column = static_cast<u32>(s * static_cast<T>(width)), row = static_cast<u32>((T(1) - t) * static_cast<T>(height));
  out.x = column < width ? column : width - 1;
  out.y = row < height ? row : height - 1;
  const T area = length(cross(horizontal, vertical));
  out.density = focus * focus / (cosine * cosine * cosine * area);
  return out;
}

// ---- Lights as the start of a subpath ----
// A probability over a triangle's area in the weights' unit. Fixed point divides by two lengths in turn, |e1| and |e2| sin
// of the angle between the edges: the product of two edges of a small light, each a small length in the unit, would
// keep too few steps.
template <class T>
PT_HD inline T per_triangle_area(const SceneView<T>& scene, T probability, const Vec3<T>& edge1, const Vec3<T>& edge2) {
  if constexpr (!std::is_floating_point_v<T>) {
    const T first = length(edge1), second = length(edge2);
    const T sine = length(cross(edge1 / first, edge2 / second));
    return constant<T>(2) * probability / to_unit(scene, first) / (to_unit(scene, second) * sine);
  } else {
    return probability / triangle_area(edge1, edge2);
  }
}

// The density with which a light subpath starts at point `at` of the light of `entry` (per area of the weights' unit,
// the light's choice included): uniform over the light's area, and for a mesh over its triangles by power. Fixed point
// divides by the area's two lengths in turn (see per_triangle_area).
template <class T>
PT_HD inline T emission_area_density(const SceneView<T>& scene, u32 entry, const Hit<T>& hit, T time) {
  const LightEntry<T>& light = scene.lights.entries[entry];
  const Primitive<T>& primitive = scene.primitives[light.primitive];
  Vec3<T> center;
  T radius;
  if (sphere_at(primitive, time, center, radius)) {
    if constexpr (!std::is_floating_point_v<T>)
      return light.pmf / (constant<T>(4) * pi<T>() * to_unit(scene, radius)) / to_unit(scene, radius);
    else
      return light.pmf / (constant<T>(4) * pi<T>() * radius * radius);
  }
  if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    if constexpr (!std::is_floating_point_v<T>)  // quad_area's two factors
      return light.pmf / to_unit(scene, q->u_extent) / abs(to_unit(scene, q->v_extent) / dot(q->normal, cross(q->du, q->dv)));
    else
      return light.pmf / quad_area(*q);
  }
  if (const auto* tri = std::get_if<Triangle<T>>(&primitive.shape)) return per_triangle_area(scene, light.pmf, tri->edge1, tri->edge2);
  if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
    const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
    const u32 start = light.first_cdf + (hit.triangle - mesh.first_triangle);
    const T share = scene.lights.triangle_cdf[start + 1] - scene.lights.triangle_cdf[start];
    Vec3<T> p[3];
    world_triangle(scene.meshes, *instance, hit.triangle, p);
    return per_triangle_area(scene, light.pmf * share, p[1] - p[0], p[2] - p[0]);
  }
  return T(0);
}

// The density of a light subpath's first direction: cosine-weighted about the normal, on either side of the light
// with probability 1/2 (an emitting surface shines from both sides), per unit solid angle.
template <class T>
PT_HD inline T emission_direction_density(T cosine) {
  return cosine / (constant<T>(2) * pi<T>());
}

// A light subpath's start: a point on a light (chosen by power, then uniformly by area), described as a hit seen from
// the direction it sends light in, and that direction. Throughput = emitted radiance x cos / (area density x direction
// density). False where the light picked is the background (its subpaths are not traced) or nothing can leave.
template <class T>
struct EmissionSample {
  SurfacePoint<T> at;
  Hit<T> hit;
  Vec3<T> direction;
  Color<T> throughput;
  T area_density, direction_density, cosine;
  u32 entry;
};

template <class T>
PT_HD inline bool sample_emission(const SceneView<T>& scene, const BounceRandom& random, T time, EmissionSample<T>& out) {
  if (scene.lights.count == 0) return false;
  const u32 entry = choose_light(scene.lights, random);
  const LightEntry<T>& light = scene.lights.entries[entry];
  if (light.primitive == kNoLight) return false;
  out.entry = entry;
  const Primitive<T>& primitive = scene.primitives[light.primitive];
  T u1, u2;
  random.uniform_pair(kDimLightPoint, u1, u2);
  Hit<T> hit{T(1), T(0), T(0), light.primitive, 0};
  Vec3<T> point, outward;
  Vec3<T> center;
  T radius;
  if (sphere_at(primitive, time, center, radius)) {
    outward = uniform_unit_vector(u1, u2);
    point = center + radius * outward;
  } else if (const auto* q = std::get_if<Quad<T>>(&primitive.shape)) {
    Vec3<T> eu, ev;
    quad_edges(*q, eu, ev);
    point = q->corner + u1 * eu + u2 * ev;
    outward = q->normal;
    hit.b1 = u1;
    hit.b2 = u2;
  } else if (const auto* t = std::get_if<Triangle<T>>(&primitive.shape)) {
    const T root = sqrt(u1);
    hit.b1 = root * (T(1) - u2);
    hit.b2 = root * u2;
    point = t->p0 + hit.b1 * t->edge1 + hit.b2 * t->edge2;
    outward = normalize(cross(t->edge1, t->edge2));
  } else if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
    const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
    hit.triangle = choose_mesh_triangle(scene.lights, mesh, light.first_cdf, random.template uniform<T>(kDimLightTriangle));
    Vec3<T> p[3];
    world_triangle(scene.meshes, *instance, hit.triangle, p);
    const T root = sqrt(u1);
    hit.b1 = root * (T(1) - u2);
    hit.b2 = root * u2;
    point = p[0] + hit.b1 * (p[1] - p[0]) + hit.b2 * (p[2] - p[0]);
    outward = normalize(cross(p[1] - p[0], p[2] - p[0]));
  } else {
    return false;
  }
  // The direction: cosine-weighted about the normal, on the side a third number picks.
  T d1, d2;
  random.uniform_pair(kDimEmissionDirection, d1, d2);
  const Vec3<T> disk = uniform_in_unit_disk(d1, d2);
  const T up = sqrt(max(T(0), T(1) - disk.x * disk.x - disk.y * disk.y));
  const Vec3<T> side = random.template uniform<T>(kDimEmissionSide) < constant<T>(0.5) ? outward : -outward;
  out.direction = normalize(frame_from_normal(side).to_world(Vec3<T>{disk.x, disk.y, up}));
  // Described as seen along the direction back onto the point, so that the normal faces the side light leaves from.
  const Ray<T> seen{point + out.direction, -out.direction, time};
  out.hit = hit;
  out.at = describe_hit(primitive, scene.triangle_attributes, scene.meshes, seen, hit, material_needs_uv(scene.materials[material_of_hit(primitive, scene.meshes, hit)], scene.textures));
  out.cosine = abs(dot(out.at.geometric_normal, out.direction));
  out.area_density = emission_area_density(scene, entry, hit, time);
  out.direction_density = emission_direction_density(out.cosine);
  if (!(out.area_density > T(0) && out.direction_density > T(0))) return false;
  const Color<T> emitted = material_emitted(scene.materials[out.at.material], out.at, scene.textures, scene.texture_data);
  out.throughput = emitted * (out.cosine / (out.area_density * out.direction_density));
  return max_component(out.throughput) > T(0);
}

// ---- Visibility between two vertices ----
// Whether the segment from `from` (a vertex, spawned towards `to`) to the point `to` is free, and the transmittance of
// the media it crosses. `target` names the surface `to` lies on (its primitive and triangle), or kNoLight for a point
// in a medium or off the scene (the lens): then any hit before it blocks. A surface is reached where the first hit is
// on it, within a 512th of the way of the point (a nearer hit on the same shape, its near side, blocks).
template <class T>
PT_HD inline bool segment_transmittance(const SceneView<T>& scene, const SurfacePoint<T>& from, const Vec3<T>& to, u32 target, u32 target_triangle, T time,
                                        const SampleRandom& random, u32 bounce, T& transmitted) {
  const Vec3<T> offset = to - from.p;
  const T distance = length(offset);
  if (!(distance > T(0))) return false;
  const Ray<T> ray = spawn_ray(from, offset / distance, time);
  T optical_depth = T(0);
  Hit<T> hit{};
  const IntersectContext<T> context{scene.boundaries, &random, bounce, &optical_depth};
  if (target == kNoLight) {
    if (bidirectional_hit(scene, ray, context, hit, distance)) return false;
  } else if (bidirectional_hit(scene, ray, context, hit, distance + distance * constant<T>(1.0 / 1024))) {
    if (hit.primitive != target || hit.triangle != target_triangle || hit.t < distance - distance * constant<T>(1.0 / 512)) return false;
  }
  transmitted = transmittance(optical_depth);
  return true;
}

// ---- The light subpath ----
// Traces the light subpath of one sample: its vertices where connections can be made are kept in `vertices` (their
// count returned), and each is joined to the camera (light tracing, t = 1), its contribution handed to `splat(x, y,
// radiance)` for the pixel it lands in. `time` is the camera sample's.
template <class T, class Splat>
PT_HD inline u32 trace_light_subpath(const SceneView<T>& scene, const SampleRandom& random, T time, Strided<LightVertex<T>> vertices, u32& rays,
                                     const Splat& splat) {
  const RenderParams<T>& params = scene.params;
  EmissionSample<T> start;
  if (params.max_depth < 2 || !sample_emission(scene, BounceRandom{&random, kLightPathBounce}, time, start)) return 0;
  Color<T> throughput = start.throughput;
  const T start_brightest = max_component(throughput);
  const T emission_density = start.area_density * start.direction_density;
  T connect_mis = mis_power(start.cosine / emission_density);
  T reverse_mis = T(0);
  T merge_mis = merging(scene) ? connect_mis * scene.params.merging.connect_share : T(0);
  Ray<T> ray = spawn_ray(start.at, start.direction, time);
  u32 count = 0;
  for (u32 segments = 1; segments < params.max_depth; ++segments) {
    Hit<T> hit{};
    ++rays;
    if (!bidirectional_hit(scene, ray, IntersectContext<T>{scene.boundaries, &random, kLightPathBounce + segments}, hit, largest<T>())) break;
    const Primitive<T>& primitive = scene.primitives[hit.primitive];
    const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
    const SurfacePoint<T> at = bidirectional_describe(scene, ray, hit, material, true);
    const bool in_medium = hit_in_medium(scene, hit);
    const Vec3<T> toward_light = -ray.direction;
    const T cosine = vertex_cosine(at, in_medium, toward_light);
    if (segments == 1) {
      // The weight of light sampling from here (s = 1) needs its density towards the point the subpath started from,
      // known only now: its density per solid angle there times cos at the light, over the emission density times
      // cos here (the distance squared cancels).
      const T direct = light_pdf(scene, start.entry, Ray<T>{at.p, -ray.direction, time}, Hit<T>{hit.t, T(0), T(0), start.hit.primitive, start.hit.triangle},
                                 start.at);
      reverse_mis = mis_power(direct * start.cosine / (emission_density * cosine));
    } else {
      const T distance = to_unit(scene, hit.t);
      reverse_mis *= mis_power(distance * distance / cosine);
    }
    connect_mis /= mis_power(cosine);
    if (merging(scene)) merge_mis /= mis_power(cosine);
    if (!material_samples_lights(material)) {
      // Mirrors, glass and fuzzy metal: no connection here; the strategies ending here have no density.
      Scatter<T> scatter;
      if (segments + 2 > params.max_depth) break;
      if (!material_scatter(material, ray, at, scene.textures, scene.texture_data, BounceRandom{&random, kLightPathBounce + segments}, scatter)) break;
      const T out_cosine = vertex_cosine(at, in_medium, scatter.ray.direction);
      // The adjoint's correction for shading normals: light paths weigh by the shading cosine towards the light side.
      const T shading_in = abs(dot(at.normal, toward_light)), shading_out = abs(dot(at.normal, scatter.ray.direction));
      if (!(shading_out > T(0) && cosine > T(0))) break;
      throughput *= scatter.attenuation * (shading_in * out_cosine / (shading_out * cosine));
      weights_after_specular(scene, out_cosine, reverse_mis, connect_mis, merge_mis);
      ray = scatter.ray;
    } else {
      // Light tracing: the vertex seen through a point of the lens.
      {
        const BounceRandom lens_random{&random, kLightPathBounce + segments};
        T lens_u, lens_v;
        lens_random.uniform_pair(kDimLens, lens_u, lens_v);
        const Vec3<T> disk = uniform_in_unit_disk(lens_u, lens_v);
        const Vec3<T> lens = scene.camera.origin + disk.x * scene.camera.lens_u + disk.y * scene.camera.lens_v;
        const Vec3<T> to_lens = lens - at.p;
        const T distance2 = unit_distance_squared(scene, to_lens);
        const Vec3<T> toward_camera = unit_direction(to_lens, distance2);
        const CameraImportance<T> seen = camera_importance(scene, lens, -toward_camera);
        T transmitted;
        if (seen.density > T(0)) {
          const ScatterValue<T> value = bidirectional_evaluate(scene, material, at, toward_camera, toward_light);
          const T camera_cosine = vertex_cosine(at, in_medium, toward_camera);
          if (max_component(value.value) > T(0) && camera_cosine > T(0)) {
            ++rays;
            if (segment_transmittance(scene, at, lens, kNoLight, 0, time, random, kLightPathBounce + segments, transmitted)) {
              const T camera_density = seen.density * camera_cosine / distance2;  // per unit area here
              const T weight =
                  T(1) / (mis_power_times(camera_density, merge_share_at(scene, in_medium) + reverse_mis + connect_mis * mis_power(value.pdf)) + T(1));
              splat(seen.x, seen.y, throughput * value.value * (weight * camera_density * transmitted / cosine));
            }
          }
        }
      }
      // Kept where a camera vertex other than the camera can still join it (or, merging, take it as its own).
      if (segments + (merging(scene) ? 1 : 2) > params.max_depth) break;
      vertices[count++] = LightVertex<T>{at, throughput, toward_light, reverse_mis, connect_mis, merge_mis, hit.primitive, hit.triangle, segments, in_medium};
      if (segments + 2 > params.max_depth) break;
      Scatter<T> scatter;
      if (!material_scatter(material, ray, at, scene.textures, scene.texture_data, BounceRandom{&random, kLightPathBounce + segments}, scatter)) break;
      if (!(scatter.pdf > T(0))) break;
      const Vec3<T> out = scatter.ray.direction;
      // The scattering of light arriving from the light side towards `out`, and the density of the reverse direction.
      const ScatterValue<T> value = bidirectional_evaluate(scene, material, at, out, toward_light);
      const T out_cosine = vertex_cosine(at, in_medium, out);
      if (!(cosine > T(0))) break;
      throughput *= value.value * (out_cosine / (cosine * scatter.pdf));
      weights_after_scattering(scene, in_medium, out_cosine, scatter.pdf, value.pdf, reverse_mis, connect_mis, merge_mis);
      ray = scatter.ray;
    }
    if (params.roulette_depth > 0 && segments >= params.roulette_depth) {
      // As the path tracer's roulette, on the throughput relative to the subpath's start.
      const T q = min(max_component(throughput) / start_brightest, constant<T>(0.95));
      if (!(BounceRandom{&random, kLightPathBounce + segments}.template uniform<T>(kDimRoulette) < q)) break;
      throughput = throughput / q;
    }
    if (!(max_component(throughput) > T(0))) break;
  }
  return count;
}

// ---- The camera subpath, joined to the light subpath ----
// The radiance camera vertex `x` receives from the light vertices: each joined by a segment whose visibility is traced.
// (`vertices` takes the writable views too, by conversion: T is deduced from the other arguments.)
template <class T>
PT_NOINLINE PT_HD Color<T> connect_to_light_vertices(const SceneView<T>& scene, const SampleRandom& random, const CameraVertex<T>& x,
                                                     std::type_identity_t<Strided<const LightVertex<T>>> vertices, u32 count, u32& rays) {
  Color<T> sum{};
  const Material<T>& material = scene.materials[x.at.material];
  for (u32 i = 0; i < count; ++i) {
    const LightVertex<T>& y = vertices[i];
    if (y.segments + x.segments + 1 > scene.params.max_depth) break;  // kept in order of length
    const Vec3<T> offset = y.at.p - x.at.p;
    const T distance2 = unit_distance_squared(scene, offset);
    if (!(distance2 > T(0))) continue;
    const Vec3<T> direction = unit_direction(offset, distance2);
    const ScatterValue<T> here = bidirectional_evaluate(scene, material, x.at, x.toward_camera, direction);
    if (!(max_component(here.value) > T(0))) continue;
    const Material<T>& light_material = scene.materials[y.at.material];
    const ScatterValue<T> there = bidirectional_evaluate(scene, light_material, y.at, -direction, y.toward_light);
    if (!(max_component(there.value) > T(0))) continue;
    const T cosine_here = vertex_cosine(x.at, x.in_medium, direction), cosine_there = vertex_cosine(y.at, y.in_medium, direction);
    const T incoming_cosine = vertex_cosine(y.at, y.in_medium, y.toward_light);
    if (!(cosine_here > T(0) && cosine_there > T(0) && incoming_cosine > T(0))) continue;
    // The densities of sampling each end's direction from the other side, per unit area at the far end.
    const T reverse_here = bidirectional_evaluate(scene, material, x.at, direction, x.toward_camera).pdf;
    const T forward_there = bidirectional_evaluate(scene, light_material, y.at, y.toward_light, -direction).pdf;
    const T camera_to_light = here.pdf * cosine_there / distance2;
    const T light_to_camera = forward_there * cosine_here / distance2;
    const T light_share = mis_power_times(camera_to_light, merge_share_at(scene, y.in_medium) + y.reverse_mis + y.connect_mis * mis_power(there.pdf));
    const T camera_share = mis_power_times(light_to_camera, merge_share_at(scene, x.in_medium) + x.reverse_mis + x.connect_mis * mis_power(reverse_here));
    const T weight = T(1) / (light_share + T(1) + camera_share);
    T transmitted;
    ++rays;
    if (!segment_transmittance(scene, x.at, y.at.p, y.in_medium ? kNoLight : y.primitive, y.triangle, x.time, random, x.segments, transmitted)) continue;
    sum += x.throughput * here.value * there.value * y.throughput * (weight * cosine_there * transmitted / (incoming_cosine * distance2));
  }
  return sum;
}

// ---- Vertex merging ----
// A merging pass keeps the light vertices of its light subpaths (one a pixel of a band of rows) in a hash grid of cells
// twice the radius wide, so that the disc about a camera vertex lies within the 2 x 2 x 2 cells about it. A cell's list
// holds the vertices' places in the band's buffers (slot i x capacity + pixel) in increasing order, so that a camera
// vertex sums what it merges in one order on every device and with any number of threads.
template <class T>
struct MergeGrid {
  u32* starts;         // cells + 1: cell c's places are entries[starts[c], starts[c + 1])
  u32* cursor;         // cells: while the grid is built, each cell's count, then where its next place goes
  u32* entries;        // the places
  Vec3<T>* positions;  // entry e's vertex's position, read before the vertex itself (most entries are not within reach)
  u32* run_starts;     // runs: while the grid is built, where each run of cells starts in `entries` (MergeGridScan)
  u32 cells;           // a power of two
  u32 runs;            // of kMergeGridRun cells each (one run where cells are fewer), a power of two
  T cell_size;         // twice the radius
};

// Cells a thread sums in turn while the cells' starts are formed from their counts.
inline constexpr u32 kMergeGridRun = 256;

// The cell of a point along one axis, kept within the range of a 32-bit integer.
template <class T>
PT_HD inline i32 merge_cell_coordinate(T value, T cell_size) {
  const T cell = floor(value / cell_size);
  const T bound = constant<T>(1073741824.0);  // 2^30
  return static_cast<i32>(cell < -bound ? -bound : cell > bound ? bound : cell);
}

PT_HD inline u32 merge_cell_hash(i32 x, i32 y, i32 z, u32 cells) {
  return ((static_cast<u32>(x) * 73856093u) ^ (static_cast<u32>(y) * 19349663u) ^ (static_cast<u32>(z) * 83492791u)) & (cells - 1);
}

template <class T>
PT_HD inline u32 merge_cell_of(const MergeGrid<T>& grid, const Vec3<T>& p) {
  return merge_cell_hash(merge_cell_coordinate(p.x, grid.cell_size), merge_cell_coordinate(p.y, grid.cell_size), merge_cell_coordinate(p.z, grid.cell_size),
                         grid.cells);
}

// Whether a light vertex goes into the grid: merging takes surface vertices only.
template <class T>
PT_HD inline bool mergeable(const LightVertex<T>& vertex) {
  return !vertex.in_medium;
}

// The buffers of a band of rows (below, with the staged schedule): merging reads the grid and the light vertices its
// places name.
template <class T>
struct BidirectionalBand;

// The radiance camera vertex `x` takes from the light vertices within the radius (at most 2 x 2 x 2 cells, each cell's
// list read once however many of them share a hash): each vertex's throughput, scattered towards the camera by x's
// material, over the disc's area and the number of light subpaths (MergeParams::normalization), weighed against
// joining and merging at the other vertices of the same path. The light vertex's throughput is power per area across
// its arrival direction; x's material value holds the shading cosine, so it is divided by the geometric one.
template <class T>
PT_NOINLINE PT_HD Color<T> merge_light_vertices(const SceneView<T>& scene, const CameraVertex<T>& x, const BidirectionalBand<T>& band) {
  const MergeGrid<T>& grid = band.grid;
  Color<T> sum{};
  if (x.in_medium) return sum;
  const MergeParams<T>& merge = scene.params.merging;
  const Material<T>& material = scene.materials[x.at.material];
  const T radius2 = merge.radius * merge.radius;
  const i32 bx = merge_cell_coordinate(x.at.p.x - merge.radius, grid.cell_size), by = merge_cell_coordinate(x.at.p.y - merge.radius, grid.cell_size),
            bz = merge_cell_coordinate(x.at.p.z - merge.radius, grid.cell_size);
  u32 visited[8];
  for (u32 k = 0; k < 8; ++k) {
    const u32 cell = merge_cell_hash(bx + static_cast<i32>(k & 1), by + static_cast<i32>((k >> 1) & 1), bz + static_cast<i32>(k >> 2), grid.cells);
    visited[k] = cell;
    bool seen = false;
    for (u32 j = 0; j < k; ++j) seen = seen || visited[j] == cell;
    if (seen) continue;
    for (u32 e = grid.starts[cell]; e < grid.starts[cell + 1]; ++e) {
      if (!(length_squared(grid.positions[e] - x.at.p) <= radius2)) continue;
      const LightVertex<T>& y = band.light_vertex_at(grid.entries[e]);
      if (y.segments + x.segments > scene.params.max_depth) continue;
      const ScatterValue<T> here = bidirectional_evaluate(scene, material, x.at, x.toward_camera, y.toward_light);
      if (!(max_component(here.value) > T(0))) continue;
      const T cosine = vertex_cosine(x.at, false, y.toward_light);
      if (!(cosine > T(0))) continue;
      const T reverse = bidirectional_evaluate(scene, material, x.at, y.toward_light, x.toward_camera).pdf;
      const T light_share = y.reverse_mis * merge.connect_share + y.merge_mis * mis_power(here.pdf);
      const T camera_share = x.reverse_mis * merge.connect_share + x.merge_mis * mis_power(reverse);
      const T weight = T(1) / (light_share + T(1) + camera_share);
      sum += here.value * y.throughput * (weight / cosine);
    }
  }
  return x.throughput * sum * merge.normalization;
}

// Light sampling from a camera vertex (s = 1): a light picked and a point or direction drawn as the path tracer draws
// them; the weight counts the light subpaths that could have made the same path as well.
template <class T>
PT_NOINLINE PT_HD Color<T> connect_to_light(const SceneView<T>& scene, const SampleRandom& random, const Ray<T>& ray, const SurfacePoint<T>& at, bool in_medium,
                                       const Material<T>& material, const Color<T>& throughput, T reverse_mis, T connect_mis, u32 bounce, u32& rays) {
  const BounceRandom bounce_random{&random, bounce};
  const u32 entry = choose_light(scene.lights, bounce_random);
  LightSample<T> light;
  if (!sample_light(scene, entry, at.p, ray.time, bounce_random, light)) return Color<T>{};
  const Vec3<T> toward_camera = -ray.direction;
  const ScatterValue<T> value = bidirectional_evaluate(scene, material, at, toward_camera, light.direction);
  if (!(max_component(value.value) > T(0))) return Color<T>{};
  const Ray<T> shadow_ray = spawn_ray(at, light.direction, ray.time);
  const LightEntry<T>& entry_data = scene.lights.entries[entry];
  T optical_depth = T(0);
  Hit<T> hit{};
  const IntersectContext<T> context{scene.boundaries, &random, bounce, &optical_depth};
  const T reach = light.distance + light.distance * constant<T>(1.0 / 1024);
  ++rays;
  const bool blocked = bidirectional_hit(scene, shadow_ray, context, hit, reach);
  if (entry_data.primitive == kNoLight) {
    // The background: only the camera subpath reaches it, so the weight is the path tracer's.
    if (blocked || !(light.pdf > T(0))) return Color<T>{};
    return throughput * value.value * background_radiance(scene.background, light.direction) *
           (light_sample_weight(light.pdf, value.pdf) * transmittance(optical_depth));
  }
  if (!blocked) {
    if (!quad_light_reached(scene, entry_data.primitive, shadow_ray, hit)) return Color<T>{};
  } else if (hit.primitive != entry_data.primitive || hit.triangle != light.triangle) {
    return Color<T>{};
  }
  const Primitive<T>& primitive = scene.primitives[hit.primitive];
  const Material<T>& light_material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
  const SurfacePoint<T> on_light = bidirectional_describe(scene, shadow_ray, hit, light_material, false);
  const T direct = light.pdf > T(0) ? light.pdf : light_pdf(scene, entry, shadow_ray, hit, on_light);
  if (!(direct > T(0))) return Color<T>{};
  const T light_cosine = abs(dot(on_light.geometric_normal, light.direction));
  const T cosine_here = vertex_cosine(at, in_medium, light.direction);
  const T emission = emission_area_density(scene, entry, hit, ray.time) * emission_direction_density(light_cosine);
  const T reverse_here = bidirectional_evaluate(scene, material, at, light.direction, toward_camera).pdf;
  const T scatter_share = mis_power(value.pdf / direct);
  const T light_share =
      light_cosine > T(0) ? mis_power_times(emission * cosine_here / (direct * light_cosine),
                                            merge_share_at(scene, in_medium) + reverse_mis + connect_mis * mis_power(reverse_here))
                          : T(0);
  const T weight = T(1) / (scatter_share + T(1) + light_share);
  return throughput * value.value * material_emitted(light_material, on_light, scene.textures, scene.texture_data) *
         (weight * transmittance(optical_depth) / direct);
}

// What the camera subpath finds by itself (s = 0) where its segment `ray` leaves the scene: the background, weighed
// against light sampling from the vertex the segment left (`scatter_pdf`: the density it was drawn with; 0 for the camera
// ray and after a specular choice, from where light sampling cannot make it), as the path tracer weighs it.
template <class T>
PT_HD inline Color<T> camera_meets_background(const SceneView<T>& scene, const Ray<T>& ray, const Color<T>& throughput, T scatter_pdf) {
  T weight = T(1);
  if (scene.lights.background != kNoLight && scatter_pdf > T(0))
    weight = scattered_light_weight(scatter_pdf, background_light_density(scene.lights.entries[scene.lights.background].pmf,
                                                                          background_pdf(scene.background, ray.direction)));
  return throughput * background_radiance(scene.background, ray.direction) * weight;
}

// The running quantities of the camera subpath's weights at the vertex its segment reaches, `distance` long (in the
// weights' unit), arriving at `cosine` to the surface.
template <class T>
PT_HD inline void weights_at_camera_vertex(const SceneView<T>& scene, T distance, T cosine, T& reverse_mis, T& connect_mis, T& merge_mis) {
  reverse_mis *= mis_power(distance * distance);
  if (cosine > T(0)) {
    reverse_mis /= mis_power(cosine);
    connect_mis /= mis_power(cosine);
    if (merging(scene)) merge_mis /= mis_power(cosine);
  }
}

// Emission the camera subpath meets (s = 0) at `at`, where its segment `ray` (of bounce `bounce`) ends: weighed against
// light sampling from the previous vertex and against the light subpaths that start at this point.
template <class T>
PT_HD inline Color<T> camera_meets_emission(const SceneView<T>& scene, const Ray<T>& ray, const Hit<T>& hit, const Material<T>& material,
                                            const SurfacePoint<T>& at, T cosine, T distance, T reverse_mis, T connect_mis, u32 bounce,
                                            const Color<T>& throughput) {
  const Color<T> emitted = material_emitted(material, at, scene.textures, scene.texture_data);
  if (!(max_component(emitted) > T(0))) return Color<T>{};
  T weight = T(1);
  const u32 entry = scene.lights.primitive_light[hit.primitive];
  if (bounce > 0 && entry != kNoLight) {
    const Ray<T> from_previous{ray.origin, ray.direction, ray.time};
    const T direct = light_pdf(scene, entry, from_previous, hit, at) * cosine / (distance * distance);
    const T emission = emission_area_density(scene, entry, hit, ray.time) * emission_direction_density(cosine);
    weight = T(1) / (T(1) + mis_power_times(direct, reverse_mis) + mis_power_times(emission, connect_mis));
  }
  return throughput * emitted * weight;
}

// Glass splits the emission the camera subpath meets next (s = 0) between its two ways on (dielectric_ways): the way the
// subpath takes meets it at its next vertex, weighed by that way's share; the other way is traced here for the emission
// it meets alone, weighed by its own share (`throughput` holds it). The expected value is the same, and every sample
// that reaches glass sees what the glass reflects, where the choice of a way would show it to a few: Schlick's
// reflectance is 4 % at normal incidence, so a small bright lamp seen in glass was a rare, very bright sample (it made
// 86 % of vcm's squared error on scenes/caustics.json). `reverse_mis`, `connect_mis` and `merge_mis` are the weights'
// running quantities at the glass, `out_cosine` the other way's cosine there; one ray more for each glass vertex.
template <class T>
PT_NOINLINE PT_HD Color<T> camera_emission_other_way(const SceneView<T>& scene, const SampleRandom& random, const SurfacePoint<T>& at,
                                                     const Vec3<T>& direction, T time, T out_cosine, T reverse_mis, T connect_mis, T merge_mis,
                                                     u32 bounce, const Color<T>& throughput, u32& rays) {
  weights_after_specular(scene, out_cosine, reverse_mis, connect_mis, merge_mis);
  const Ray<T> ray = spawn_ray(at, direction, time);
  Hit<T> hit{};
  ++rays;
  if (!bidirectional_hit(scene, ray, IntersectContext<T>{scene.boundaries, &random, bounce + 1}, hit, largest<T>()))
    return camera_meets_background(scene, ray, throughput, T(0));
  const Material<T>& material = scene.materials[material_of_hit(scene.primitives[hit.primitive], scene.meshes, hit)];
  if (!material_emits(material)) return Color<T>{};
  const SurfacePoint<T> on_light = bidirectional_describe(scene, ray, hit, material, true);
  const T cosine = vertex_cosine(on_light, false, ray.direction), distance = to_unit(scene, hit.t);
  weights_at_camera_vertex(scene, distance, cosine, reverse_mis, connect_mis, merge_mis);
  return camera_meets_emission(scene, ray, hit, material, on_light, cosine, distance, reverse_mis, connect_mis, bounce + 1, throughput);
}

// The camera subpath of one sample, from camera ray `ray`: returns what it finds by itself (s = 0: emission and the
// background met) and by light sampling (s = 1), and hands each vertex where light vertices can be joined to
// `connect(const CameraVertex<T>&)`, in order along the path.
template <class T, class Connect>
PT_HD inline Color<T> trace_camera_subpath(const SceneView<T>& scene, const SampleRandom& random, Ray<T> ray, u32& rays, const Connect& connect) {
  const RenderParams<T>& params = scene.params;
  const CameraImportance<T> primary = camera_importance(scene, ray.origin, ray.direction);
  Color<T> radiance{};
  Color<T> throughput = Color<T>::splat(T(1));
  T reverse_mis = primary.density > T(0) ? mis_power(T(1) / primary.density) : T(0);
  T connect_mis = T(0), merge_mis = T(0);
  T scatter_pdf = T(0);     // of the last direction, 0 for the camera ray and specular choices (as the path tracer keeps it)
  T emission_share = T(1);  // of what the next vertex meets by itself: the way's share where glass split it
  for (u32 bounce = 0; bounce < params.max_depth; ++bounce) {
    Hit<T> hit{};
    ++rays;
    if (!bidirectional_hit(scene, ray, IntersectContext<T>{scene.boundaries, &random, bounce}, hit, largest<T>())) {
      radiance += camera_meets_background(scene, ray, throughput * emission_share, scatter_pdf);
      break;
    }
    const Primitive<T>& primitive = scene.primitives[hit.primitive];
    const Material<T>& material = scene.materials[material_of_hit(primitive, scene.meshes, hit)];
    const SurfacePoint<T> at = bidirectional_describe(scene, ray, hit, material, true);
    const bool in_medium = hit_in_medium(scene, hit);
    const T cosine = vertex_cosine(at, in_medium, ray.direction);
    const T distance = to_unit(scene, hit.t);
    weights_at_camera_vertex(scene, distance, cosine, reverse_mis, connect_mis, merge_mis);
    radiance += camera_meets_emission(scene, ray, hit, material, at, cosine, distance, reverse_mis, connect_mis, bounce, throughput * emission_share);
    emission_share = T(1);
    if (bounce + 1 >= params.max_depth) break;
    if (material_samples_lights(material)) {
      if (scene.lights.count > 0)
        radiance += connect_to_light(scene, random, ray, at, in_medium, material, throughput, reverse_mis, connect_mis, bounce, rays);
      connect(CameraVertex<T>{at, throughput, -ray.direction, reverse_mis, connect_mis, merge_mis, ray.time, bounce + 1, in_medium});
    }
    Scatter<T> scatter;
    const BounceRandom bounce_random{&random, bounce};
    if (const auto* glass = std::get_if<Dielectric<T>>(&material)) {
      // Glass's ways made once, for the scattering and for the split.
      const DielectricWays<T> ways = dielectric_ways(*glass, ray, at, bounce_random, true);
      scatter = dielectric_scatter(*glass, ray, at, ways);
      if (ways.other_share > T(0)) {
        radiance += camera_emission_other_way(scene, random, at, ways.other, ray.time, vertex_cosine(at, false, ways.other), reverse_mis, connect_mis,
                                              merge_mis, bounce, throughput * scatter.attenuation * ways.other_share, rays);
        emission_share = ways.taken_share;
      }
    } else if (!material_scatter(material, ray, at, scene.textures, scene.texture_data, bounce_random, scatter)) {
      break;
    }
    const T out_cosine = vertex_cosine(at, in_medium, scatter.ray.direction);
    if (scatter.pdf > T(0)) {
      const T reverse = bidirectional_evaluate(scene, material, at, scatter.ray.direction, -ray.direction).pdf;
      weights_after_scattering(scene, in_medium, out_cosine, scatter.pdf, reverse, reverse_mis, connect_mis, merge_mis);
    } else {
      weights_after_specular(scene, out_cosine, reverse_mis, connect_mis, merge_mis);
    }
    throughput *= scatter.attenuation;
    scatter_pdf = scatter.pdf;
    ray = scatter.ray;
    if (params.roulette_depth > 0 && bounce + 1 >= params.roulette_depth) {
      const T q = min(max_component(throughput), constant<T>(0.95));
      if (!(bounce_random.template uniform<T>(kDimRoulette) < q)) break;
      throughput = throughput / q;
    }
  }
  return radiance;
}

// The start of a sample of pixel (x, y): its random numbers and camera ray; the light subpath is traced from the ray's time.
template <class T>
struct BidirectionalStart {
  SampleRandom random;
  Ray<T> ray;
};

template <class T>
PT_HD inline BidirectionalStart<T> start_bidirectional_sample(const SceneView<T>& scene, u32 x, u32 y, u32 sample) {
  const RenderParams<T>& params = scene.params;
  const SampleRandom random = path_random(params, y * params.width + x, sample);
  return BidirectionalStart<T>{random, camera_ray(scene.camera, params.width, params.height, x, y, random)};
}

// What a sample adds to its own pixel: what the camera subpath found by itself and by light sampling, plus the sum of
// its vertices' connections (added in the order of the vertices along the path, whichever schedule made them).
template <class T>
PT_HD inline Color<T> bidirectional_radiance(const Color<T>& direct, const Color<T>& connected) {
  return direct + connected;
}

// One sample of pixel (x, y) by bidirectional path tracing in one go: the light subpath first (its splats handed to
// `splat`), then the camera subpath, each of its vertices joined to the light subpath's as it is reached.
template <class T, class Splat>
PT_HD inline SampleResult<T> trace_bidirectional_sample(const SceneView<T>& scene, u32 x, u32 y, u32 sample, const Splat& splat) {
  const BidirectionalStart<T> start = start_bidirectional_sample(scene, x, y, sample);
  u32 rays = 0;
  LightVertexStore<T> store;
  const Strided<LightVertex<T>> vertices{store.vertices(), 1};
  const u32 count = trace_light_subpath(scene, start.random, start.ray.time, vertices, rays, splat);
  Color<T> connected{};
  const Color<T> direct = trace_camera_subpath(scene, start.random, start.ray, rays, [&](const CameraVertex<T>& vertex) {
    connected += connect_to_light_vertices(scene, start.random, vertex, vertices, count, rays);
  });
  return SampleResult<T>{bidirectional_radiance(direct, connected), rays};
}

// ---- Splats ----
// Light tracing adds to pixels other than the sample's own. Those sums are kept as integers (fixed point with 32
// fraction bits, three a pixel) added atomically: integer addition does not depend on order, so the image is the
// same whatever the threads, the tiles or the device, and the sums of one sample are folded into the film (in
// double, after that sample's own contributions) before the next sample's are made.
inline constexpr double kSplatScale = 4294967296.0;  // 2^32
inline constexpr double kLargestSplat = 1e9;         // beyond this (far outside any image's range) a splat is clamped

PT_HD inline u64 splat_bits(double value) {
  if (!(value > 0)) return 0;  // also NaN
  if (value > kLargestSplat) value = kLargestSplat;
  return static_cast<u64>(value * kSplatScale + 0.5);
}

struct SplatFilm {
  u64* sums;  // three a pixel
  u32 width;
  template <class T>
  PT_HD void operator()(u32 x, u32 y, const Color<T>& value) const {
    if (!is_finite(value)) return;
    u64* pixel = sums + 3 * (static_cast<std::size_t>(y) * width + x);
    atomic_fetch_add_u64(pixel + 0, splat_bits(static_cast<double>(value.x)));
    atomic_fetch_add_u64(pixel + 1, splat_bits(static_cast<double>(value.y)));
    atomic_fetch_add_u64(pixel + 2, splat_bits(static_cast<double>(value.z)));
  }
};

// The bidirectional kernel over an image: one sample of pixel (x, first_row + y) added to the film (as
// MegakernelSample adds one), its splats to `splats`.
template <class T>
struct BidirectionalSample {
  SceneView<T> scene;
  FilmPixel* film;
  SplatFilm splats;
  u32 sample;
  PT_HD void operator()(u32 x, u32 y) const {
    FilmPixel& pixel = film[static_cast<std::size_t>(y) * scene.params.width + x];
    FilmPixel sum = pixel;
    add_sample(sum, trace_bidirectional_sample(scene, x, y, sample, splats), sample);
    pixel = sum;
  }
};

// ---- The staged schedule ----
// On GPUs one kernel a sample leaves most of a warp idle: each thread waits for the longest pair of subpaths in its warp
// and then for the longest run of connections. The staged schedule makes the connections a launch of their own, over
// a band of the image's rows: (1) each pixel traces its light subpath (splats included), then, in a second launch, its
// camera subpath, keeping the vertices of both and what the camera subpath found by itself, and queueing its camera
// vertices; (2) one thread per queued camera vertex joins it to its pixel's light vertices; (3) each pixel adds its
// sample to the film. The sums are formed as trace_bidirectional_sample forms them, in the same order, so both
// schedules make the same image bit for bit.

// The connections of one camera vertex, and the rays they traced.
template <class T>
struct ConnectionSum {
  Color<T> radiance;
  u32 rays;
};

// The buffers of a band of rows: camera vertex i of every pixel side by side ([i][pixel], `capacity` pixels a row of
// slots); light vertices so too for the stages (on a GPU neighbouring threads read neighbouring memory), each pixel's
// together for the host's one-launch merging (a pixel's connections read its own vertices one after the other).
template <class T>
struct BidirectionalBand {
  LightVertex<T>* light_vertices;    // (max_depth - 2) slots a pixel; merging, (max_depth - 1)
  CameraVertex<T>* camera_vertices;  // (max_depth - 1) slots
  ConnectionSum<T>* connections;     // one a camera vertex
  SampleResult<T>* direct;           // what the camera subpath found by itself, and all the rays traced in stage 1
  u32* light_counts;
  u32* camera_counts;
  u32* connect_queue;   // the camera vertices written, each as its place i * capacity + pixel, in no particular order
  u32* connect_length;  // of the queue
  u32 capacity;   // pixels a band holds
  u32 first_row;  // of the band being rendered
  u32 pixels;     // of the band being rendered (whole rows)
  MergeGrid<T> grid;  // the band's light vertices by place, in a merging pass

  u32 light_pixel_stride, light_slot_stride;  // light vertex i of pixel p at light_vertices[p * pixel stride + i * slot stride]

  PT_HD Strided<LightVertex<T>> light_vertices_of(u32 pixel) const {
    return {light_vertices + static_cast<std::size_t>(pixel) * light_pixel_stride, light_slot_stride};
  }
  // A light vertex by its place in the merging grid's lists, i x capacity + pixel whatever the layout (so that the
  // lists' order, and the film, are the same on every device).
  PT_HD const LightVertex<T>& light_vertex_at(u32 place) const { return light_vertices_of(place % capacity)[place / capacity]; }
  PT_HD CameraVertex<T>& camera_vertex(u32 pixel, u32 i) const { return camera_vertices[static_cast<std::size_t>(i) * capacity + pixel]; }
  PT_HD ConnectionSum<T>& connection(u32 pixel, u32 i) const { return connections[static_cast<std::size_t>(i) * capacity + pixel]; }
};

// Stage 1, over the band's pixels (x, row within the band), in two launches, each a kernel of half the size: the light
// subpath of one sample (its splats made, its vertices kept), then the camera subpath (its vertices kept).
template <class T>
struct BidirectionalLightSubpaths {
  SceneView<T> scene;
  BidirectionalBand<T> band;
  SplatFilm splats;
  u32 sample;
  PT_HD void operator()(u32 x, u32 row) const {
    const u32 pixel = row * scene.params.width + x;
    const BidirectionalStart<T> start = start_bidirectional_sample(scene, x, band.first_row + row, sample);
    u32 rays = 0;
    band.light_counts[pixel] = trace_light_subpath(scene, start.random, start.ray.time, band.light_vertices_of(pixel), rays, splats);
    band.direct[pixel] = SampleResult<T>{Color<T>{}, rays};
  }
};

template <class T>
struct BidirectionalCameraSubpaths {
  SceneView<T> scene;
  BidirectionalBand<T> band;
  u32 sample;
  PT_HD void operator()(u32 x, u32 row) const {
    const u32 pixel = row * scene.params.width + x;
    const BidirectionalStart<T> start = start_bidirectional_sample(scene, x, band.first_row + row, sample);
    u32 rays = band.direct[pixel].rays;  // the light subpath's
    // Without light vertices its vertices join nothing (their connections would add zero): none are kept, unless
    // they can merge with other pixels' light vertices.
    const bool joined = band.light_counts[pixel] > 0 || merging(scene);
    u32 cameras = 0;
    const Color<T> direct = trace_camera_subpath(scene, start.random, start.ray, rays, [&](const CameraVertex<T>& vertex) {
      if (!joined) return;
      band.camera_vertex(pixel, cameras) = vertex;
      band.connect_queue[queue_push(band.connect_length)] = cameras * band.capacity + pixel;
      ++cameras;
    });
    band.camera_counts[pixel] = cameras;
    band.direct[pixel] = SampleResult<T>{direct, rays};
  }
};

// What a camera vertex of pixel `pixel` of the band takes from the light vertices: its joins to the pixel's own, then,
// in a merging pass, its merges with the grid's (the one sum both schedules add, in this order).
template <class T>
PT_HD inline Color<T> joined_radiance(const SceneView<T>& scene, const SampleRandom& random, const BidirectionalBand<T>& band, u32 pixel,
                                      const CameraVertex<T>& vertex, u32& rays) {
  Color<T> sum = connect_to_light_vertices(scene, random, vertex, band.light_vertices_of(pixel), band.light_counts[pixel], rays);
  if (merging(scene)) sum += merge_light_vertices(scene, vertex, band);
  return sum;
}

// Stage 2, over the queue of camera vertices written: each joined to its pixel's light vertices. Where it is in the queue
// does not matter: its sum goes to the vertex's own place.
template <class T>
struct BidirectionalConnect {
  SceneView<T> scene;
  BidirectionalBand<T> band;
  u32 sample;
  PT_HD void operator()(u32 item) const {
    const u32 place = band.connect_queue[item];
    const u32 i = place / band.capacity, pixel = place % band.capacity;
    const SampleRandom random = path_random(scene.params, band.first_row * scene.params.width + pixel, sample);
    u32 rays = 0;
    const Color<T> sum = joined_radiance(scene, random, band, pixel, band.camera_vertex(pixel, i), rays);
    band.connection(pixel, i) = ConnectionSum<T>{sum, rays};
  }
};

// Between stage 1's two launches of a merging pass, the grid of the band's light vertices is built: each cell's vertices
// counted (into grid.cursor: MergeGridPlace), the counts summed into starts (MergeGridScan), each vertex's place written
// at its cell's cursor (in whatever order the threads come), and each cell's list sorted, so that the grid is the same
// on every device.
// Both passes over the band's light vertices take a slot of the vertex's cell by an atomic addition: counting (the
// cursor starts at zero) or placing (the cursor starts at the cell's start, and the vertex's place goes to its slot).
template <class T>
struct MergeGridPlace {
  BidirectionalBand<T> band;
  bool write;  // false: count only
  PT_HD void operator()(u32 pixel) const {
    const Strided<LightVertex<T>> vertices = band.light_vertices_of(pixel);
    for (u32 i = 0; i < band.light_counts[pixel]; ++i) {
      if (!mergeable(vertices[i])) continue;
      const u32 slot = atomic_fetch_add(&band.grid.cursor[merge_cell_of(band.grid, vertices[i].at.p)], 1u);
      if (write) band.grid.entries[slot] = i * band.capacity + pixel;
    }
  }
};

// Heapsort of one cell's places: in place, without recursion, n log n however crowded a cell (a caustic's focus); then
// the vertices' positions beside them.
template <class T>
struct MergeGridSort {
  BidirectionalBand<T> band;
  PT_HD static void sift_down(u32* a, u32 root, u32 n) {
    while (2 * root + 1 < n) {
      u32 child = 2 * root + 1;
      if (child + 1 < n && a[child] < a[child + 1]) ++child;
      if (!(a[root] < a[child])) return;
      const u32 t = a[root];
      a[root] = a[child];
      a[child] = t;
      root = child;
    }
  }
  PT_HD void operator()(u32 cell) const {
    const MergeGrid<T>& grid = band.grid;
    u32* a = grid.entries + grid.starts[cell];
    const u32 n = grid.starts[cell + 1] - grid.starts[cell];
    if (n >= 2) {
      for (u32 i = n / 2; i-- > 0;) sift_down(a, i, n);
      for (u32 end = n - 1; end > 0; --end) {
        const u32 t = a[0];
        a[0] = a[end];
        a[end] = t;
        sift_down(a, 0, end);
      }
    }
    for (u32 e = 0; e < n; ++e) grid.positions[grid.starts[cell] + e] = band.light_vertex_at(a[e]).at.p;
  }
};

// The cells' starts, summed from their counts on the device (so that building the grid never waits for the host), in
// three launches: `runs` threads each sum a run of cells; one thread turns the runs' sums into their starts; `runs`
// threads each write their run's starts (and the cursors the places are written at). Integer sums: the same on every
// device whatever the order of the threads.
template <class T>
struct MergeGridScan {
  enum Step : u32 { kRunSums, kRunStarts, kCellStarts };
  MergeGrid<T> grid;
  Step step;
  PT_HD void operator()(u32 run) const {
    const u32 length = grid.cells / grid.runs, first = run * length;
    if (step == kRunSums) {
      u32 sum = 0;
      for (u32 c = first; c < first + length; ++c) sum += grid.cursor[c];
      grid.run_starts[run] = sum;
    } else if (step == kRunStarts) {
      u32 total = 0;
      for (u32 r = 0; r < grid.runs; ++r) {
        const u32 sum = grid.run_starts[r];
        grid.run_starts[r] = total;
        total += sum;
      }
      grid.starts[grid.cells] = total;
    } else {
      u32 start = grid.run_starts[run];
      for (u32 c = first; c < first + length; ++c) {
        const u32 count = grid.cursor[c];
        grid.starts[c] = start;
        grid.cursor[c] = start;
        start += count;
      }
    }
  }
};

// Stage 3, over the band's pixels: the sample added to the film (of the whole image), its connections summed in order.
template <class T>
struct BidirectionalGather {
  BidirectionalBand<T> band;
  FilmPixel* film;
  u32 width;
  u32 sample;
  PT_HD void operator()(u32 pixel) const {
    SampleResult<T> result = band.direct[pixel];
    Color<T> connected{};
    const u32 count = band.camera_counts[pixel];
    for (u32 i = 0; i < count; ++i) {
      const ConnectionSum<T>& c = band.connection(pixel, i);
      connected += c.radiance;
      result.rays += c.rays;
    }
    result.radiance = bidirectional_radiance(result.radiance, connected);
    FilmPixel& target = film[static_cast<std::size_t>(band.first_row) * width + pixel];
    FilmPixel sum = target;
    add_sample(sum, result, sample);
    target = sum;
  }
};

// A merging pass's camera side in one launch over the band's pixels, where one kernel a sample suits the device (the
// host): the camera subpath, each of its vertices joined to its pixel's light vertices and merged with the grid's as it
// is reached, and the sample added to the film. The sums are formed as stages 1 to 3 form them, in the same order, so
// both make the same film bit for bit.
template <class T>
struct VertexMergingCameraSample {
  SceneView<T> scene;
  BidirectionalBand<T> band;
  FilmPixel* film;
  u32 sample;
  PT_HD void operator()(u32 x, u32 row) const {
    const u32 width = scene.params.width, pixel = row * width + x;
    const BidirectionalStart<T> start = start_bidirectional_sample(scene, x, band.first_row + row, sample);
    u32 rays = band.direct[pixel].rays;  // the light subpath's
    Color<T> connected{};
    const Color<T> direct = trace_camera_subpath(scene, start.random, start.ray, rays, [&](const CameraVertex<T>& vertex) {
      connected += joined_radiance(scene, start.random, band, pixel, vertex, rays);
    });
    FilmPixel& target = film[static_cast<std::size_t>(band.first_row) * width + pixel];
    FilmPixel total = target;
    add_sample(total, SampleResult<T>{bidirectional_radiance(direct, connected), rays}, sample);
    target = total;
  }
};

// Folds one sample's splat sums into the film and clears them, pixel by pixel.
struct FoldSplats {
  FilmPixel* film;
  u64* sums;
  PT_HD void operator()(u32 pixel) const {
    u64* s = sums + 3 * static_cast<std::size_t>(pixel);
    if ((s[0] | s[1] | s[2]) == 0) return;
    FilmPixel& p = film[pixel];
    p.r += static_cast<double>(s[0]) / kSplatScale;
    p.g += static_cast<double>(s[1]) / kSplatScale;
    p.b += static_cast<double>(s[2]) / kSplatScale;
    s[0] = s[1] = s[2] = 0;
  }
};

}  // namespace pt
