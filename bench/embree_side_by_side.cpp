// Embree 3 as the CPU anchor: the same rays (camera rays, diffuse bounces from their hits, shadow rays towards a
// point above the scene) through Embree's single-ray queries (rtcIntersect1, rtcOccluded1) and through our
// eight-wide CPU traversal, one thread each (shadow rays stopping at their first blocker, as the renderer's do, and
// again by the closest-hit search they used before), over the same geometry: each mesh once, placed by instances as the
// scene places it, and the scene's other shapes (spheres, quads, triangles) as Embree user geometry that calls our
// own intersection code. Built only where Debian's libembree-dev is installed; the renderer never depends on it.
// Usage: pt_embree_side_by_side SCENE [WIDTH HEIGHT [ROUNDS [BATCH]]]   (BATCH: only the batch of that name, e.g.
// "diffuse bounce", so that a profiler's count of `ours` and `embree` is that batch's alone)
#include <embree3/rtcore.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"

namespace pt {
namespace {

using Clock = std::chrono::steady_clock;

struct RayBatch {
  std::string name;
  std::vector<Ray<float>> rays;
  std::vector<float> t_max;  // infinity, or the distance to the light for shadow rays
  bool shadow = false;
  bool closest = false;  // a shadow batch walked by our closest-hit search instead of stopping at the first blocker
};

// The scene's other shapes, as Embree user geometry: their bounds here, their intersection our own.
struct UserShapes {
  const SceneView<float>* scene;
  std::vector<u32> primitives;  // index in the flat scene of each user primitive
};

RTCBounds bounds_of(const Shape<float>& shape) {
  Vec3<float> lo{}, hi{};
  if (const auto* s = std::get_if<Sphere<float>>(&shape)) {
    const Vec3<float> r = Vec3<float>::splat(s->radius);
    lo = s->center - r, hi = s->center + r;
  } else if (const auto* q = std::get_if<Quad<float>>(&shape)) {
    Vec3<float> du, dv;
    quad_edges(*q, du, dv);
    const Vec3<float> corners[4] = {q->corner, q->corner + du, q->corner + dv, q->corner + du + dv};
    lo = hi = corners[0];
    for (const Vec3<float>& c : corners) lo = vmin(lo, c), hi = vmax(hi, c);
  } else if (const auto* t = std::get_if<Triangle<float>>(&shape)) {
    const Vec3<float> corners[3] = {t->p0, t->p0 + t->edge1, t->p0 + t->edge2};
    lo = hi = corners[0];
    for (const Vec3<float>& c : corners) lo = vmin(lo, c), hi = vmax(hi, c);
  } else {
    std::fprintf(stderr, "the benchmark takes meshes, spheres, quads and triangles only\n");
    std::exit(2);
  }
  // A little room: our intersection accepts hits within its rounding bound of the surface.
  const float pad = 1e-4f * std::max({std::abs(lo.x), std::abs(lo.y), std::abs(lo.z), std::abs(hi.x), std::abs(hi.y), std::abs(hi.z), 1.0f});
  return RTCBounds{lo.x - pad, lo.y - pad, lo.z - pad, 0, hi.x + pad, hi.y + pad, hi.z + pad, 0};
}

void user_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* shapes = static_cast<const UserShapes*>(args->geometryUserPtr);
  *args->bounds_o = bounds_of(shapes->scene->primitives[shapes->primitives[args->primID]].shape);
}

// Our intersection of one user primitive with an Embree ray (one ray a call: rtcIntersect1 and rtcOccluded1).
bool user_hit(const UserShapes& shapes, unsigned primitive, const RTCRay& ray, Hit<float>& hit) {
  const Ray<float> r{{ray.org_x, ray.org_y, ray.org_z}, {ray.dir_x, ray.dir_y, ray.dir_z}, ray.time};
  const u32 index = shapes.primitives[primitive];
  const IntersectContext<float> context{shapes.scene->boundaries, nullptr, 0};
  return intersect_primitive(shapes.scene->primitives[index], index, context, r, hit_distance_min<float>(), ray.tfar, hit);
}

void user_intersect(const RTCIntersectFunctionNArguments* args) {
  if (!args->valid[0]) return;
  RTCRayHit& rh = *reinterpret_cast<RTCRayHit*>(args->rayhit);
  Hit<float> hit{};
  if (!user_hit(*static_cast<const UserShapes*>(args->geometryUserPtr), args->primID, rh.ray, hit)) return;
  rh.ray.tfar = hit.t;
  rh.hit.geomID = args->geomID;
  rh.hit.primID = args->primID;
  rh.hit.instID[0] = args->context->instID[0];
  rh.hit.u = hit.b1, rh.hit.v = hit.b2;
  rh.hit.Ng_x = rh.hit.Ng_y = 0, rh.hit.Ng_z = 1;
}

void user_occluded(const RTCOccludedFunctionNArguments* args) {
  if (!args->valid[0]) return;
  RTCRay& ray = *reinterpret_cast<RTCRay*>(args->ray);
  Hit<float> hit{};
  if (user_hit(*static_cast<const UserShapes*>(args->geometryUserPtr), args->primID, ray, hit)) ray.tfar = -std::numeric_limits<float>::infinity();
}

// The flat scene's geometry in Embree: one triangle geometry per mesh in a scene of its own, instanced as the
// scene's primitives place it; the other shapes as one user geometry.
RTCScene embree_scene(RTCDevice device, const FlatScene<float>& flat, const SceneView<float>& view, UserShapes& user) {
  RTCScene top = rtcNewScene(device);
  std::vector<RTCScene> meshes(flat.meshes.size(), nullptr);
  for (std::size_t m = 0; m < flat.meshes.size(); ++m) {
    const MeshRecord& record = flat.meshes[m];
    u32 vertices = 0;
    for (u32 t = 0; t < record.triangle_count; ++t)
      for (u32 k : flat.mesh_triangles[record.first_triangle + t].vertex) vertices = std::max(vertices, k + 1);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices));
    for (u32 i = 0; i < vertices; ++i) {
      const Vec3<float>& p = flat.mesh_positions[record.first_vertex + i];
      v[3 * i] = p.x, v[3 * i + 1] = p.y, v[3 * i + 2] = p.z;
    }
    auto* index = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), record.triangle_count));
    for (u32 t = 0; t < record.triangle_count; ++t)
      for (int k = 0; k < 3; ++k) index[3 * t + k] = flat.mesh_triangles[record.first_triangle + t].vertex[k];
    rtcCommitGeometry(geometry);
    meshes[m] = rtcNewScene(device);
    rtcAttachGeometry(meshes[m], geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(meshes[m]);
  }
  user.scene = &view;
  for (u32 i = 0; i < flat.primitives.size(); ++i) {
    const Primitive<float>& primitive = flat.primitives[i];
    if (const auto* instance = std::get_if<MeshInstance<float>>(&primitive.shape)) {
      RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(geometry, meshes[instance->mesh]);
      float rows[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
      if (instance->transform != kNoTransform) {
        const AffineRows<float>& m = flat.instance_transforms[instance->transform].to_world;
        for (int r = 0; r < 3; ++r) {
          rows[4 * r] = m.row[r].x, rows[4 * r + 1] = m.row[r].y, rows[4 * r + 2] = m.row[r].z;
          rows[4 * r + 3] = r == 0 ? m.translation.x : r == 1 ? m.translation.y : m.translation.z;
        }
      }
      rtcSetGeometryTransform(geometry, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, rows);
      rtcCommitGeometry(geometry);
      rtcAttachGeometry(top, geometry);
      rtcReleaseGeometry(geometry);
    } else {
      user.primitives.push_back(i);
    }
  }
  if (!user.primitives.empty()) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(user.primitives.size()));
    rtcSetGeometryUserData(geometry, &user);
    rtcSetGeometryBoundsFunction(geometry, user_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geometry, user_intersect);
    rtcSetGeometryOccludedFunction(geometry, user_occluded);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(top, geometry);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(top);
  for (RTCScene s : meshes) rtcReleaseScene(s);
  return top;
}

// Camera rays (one a pixel, the renderer's own), then from each camera ray's hit a cosine-distributed bounce about
// the surface's normal and a shadow ray towards a point above the scene's middle.
std::vector<RayBatch> make_rays(const SceneView<float>& scene, u32 width, u32 height) {
  RayBatch camera{"camera", {}, {}, false}, bounce{"diffuse bounce", {}, {}, false}, shadow{"shadow", {}, {}, true};
  // The extent of what the camera sees: the light goes above its middle.
  Vec3<float> lo = Vec3<float>::splat(1e30f), hi = Vec3<float>::splat(-1e30f);
  std::vector<SurfacePoint<float>> hits;
  for (u32 y = 0; y < height; ++y)
    for (u32 x = 0; x < width; ++x) {
      const SampleRandom random = SampleRandom::make(1, y * width + x, 0, scene.params.sampler);
      const Ray<float> ray = camera_ray(scene.camera, width, height, x, y, random);
      camera.rays.push_back(ray);
      camera.t_max.push_back(largest<float>());
      Hit<float> hit{};
      if (!closest_hit(scene, ray, IntersectContext<float>{scene.boundaries, &random, 0}, hit)) continue;
      const Primitive<float>& primitive = scene.primitives[hit.primitive];
      const SurfacePoint<float> at = describe_hit(primitive, scene.triangle_attributes, scene.meshes, ray, hit, false, false);
      hits.push_back(at);
      lo = vmin(lo, at.p), hi = vmax(hi, at.p);
      const BounceRandom bounce_random{&random, 0};
      float u1, u2;
      bounce_random.uniform_pair(kDimScatter, u1, u2);
      const ShadingFrame<float> frame = frame_from_normal(at.normal);
      const float r = std::sqrt(u1), phi = 6.2831853f * u2;
      const Vec3<float> local{r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1 - u1))};
      bounce.rays.push_back(spawn_ray(at, frame.to_world(local), ray.time));
      bounce.t_max.push_back(largest<float>());
    }
  const Vec3<float> middle = (lo + hi) * 0.5f, size = hi - lo;
  const Vec3<float> light = middle + Vec3<float>{0, 0.5f * std::max({size.x, size.y, size.z}) + size.y, 0};
  for (const SurfacePoint<float>& at : hits) {
    const Ray<float> ray = spawn_ray(at, normalize(light - at.p), 0.0f);
    shadow.rays.push_back(ray);
    shadow.t_max.push_back(length(light - ray.origin));
  }
  RayBatch shadow_closest = shadow;
  shadow_closest.name = "shadow, closest";
  shadow_closest.closest = true;
  return {camera, bounce, shadow, shadow_closest};
}

struct Timing {
  double seconds;
  u64 hits;
};

// Not inlined, so that a profiler counts each side apart (callgrind with BATCH: docs in BENCHMARKS.md).
__attribute__((noinline)) Timing ours(const SceneView<float>& scene, const RayBatch& batch) {
  u64 hits = 0;
  const auto start = Clock::now();
  for (std::size_t i = 0; i < batch.rays.size(); ++i) {
    Hit<float> hit{};
    IntersectContext<float> context{scene.boundaries, nullptr, 0};
    if (batch.shadow && !batch.closest) context.blocked_before = batch.t_max[i];  // as the renderer's shadow rays towards the sky
    hits += closest_hit(scene, batch.rays[i], context, hit, batch.t_max[i]);
  }
  return {std::chrono::duration<double>(Clock::now() - start).count(), hits};
}

__attribute__((noinline)) Timing embree(RTCScene scene, const RayBatch& batch) {
  u64 hits = 0;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const auto start = Clock::now();
  for (std::size_t i = 0; i < batch.rays.size(); ++i) {
    const Ray<float>& r = batch.rays[i];
    RTCRay ray{r.origin.x, r.origin.y, r.origin.z, 0, r.direction.x, r.direction.y, r.direction.z, r.time, batch.t_max[i], ~0u, 0, 0};
    if (batch.shadow) {
      rtcOccluded1(scene, &context, &ray);
      hits += ray.tfar < 0;
    } else {
      RTCRayHit rh{ray, {}};
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &context, &rh);
      hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
  }
  return {std::chrono::duration<double>(Clock::now() - start).count(), hits};
}

}  // namespace
}  // namespace pt

int main(int argc, char** argv) {
  using namespace pt;
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCENE [WIDTH HEIGHT [ROUNDS [BATCH]]]\n", argv[0]);
    return 2;
  }
  try {
    const u32 width = argc > 3 ? static_cast<u32>(std::atoi(argv[2])) : 640, height = argc > 3 ? static_cast<u32>(std::atoi(argv[3])) : 360;
    const int rounds = argc > 4 ? std::atoi(argv[4]) : 5;
    const SceneDescription description = load_scene_file(argv[1], ModelReferences::kAnywhere);
    RenderSettings settings = description.render;
    settings.width = width, settings.height = height;
    const FlatScene<float> flat = flatten_scene<float>(description, settings);
    const SceneView<float> view = flat.view();
    RTCDevice device = rtcNewDevice("threads=1");
    UserShapes user;
    const auto build_start = Clock::now();
    RTCScene scene = embree_scene(device, flat, view, user);
    const double build = std::chrono::duration<double>(Clock::now() - build_start).count();
    u64 triangles = 0;
    for (const MeshRecord& m : flat.meshes) triangles += m.triangle_count;
    std::printf("%s: %zu primitives, %zu meshes (%llu triangles), %u x %u camera rays; Embree build %.3f s (1 thread), ours %.3f s\n", argv[1],
                flat.primitives.size(), flat.meshes.size(), static_cast<unsigned long long>(triangles), width, height, build, flat.bvh_seconds);
    std::printf("%-15s %9s %11s %11s %9s %9s %8s\n", "rays", "count", "ours Mray/s", "Embree", "ours/Embree", "hits ours", "Embree");
    for (const RayBatch& batch : make_rays(view, width, height)) {
      if (argc > 5 && batch.name != argv[5]) continue;
      std::vector<double> ours_rate, embree_rate;
      Timing o{}, e{};
      for (int r = 0; r < rounds; ++r) {  // alternately, so that drift in the machine's speed hits both
        o = ours(view, batch);
        e = embree(scene, batch);
        ours_rate.push_back(batch.rays.size() / o.seconds / 1e6);
        embree_rate.push_back(batch.rays.size() / e.seconds / 1e6);
      }
      std::sort(ours_rate.begin(), ours_rate.end());
      std::sort(embree_rate.begin(), embree_rate.end());
      const double a = ours_rate[ours_rate.size() / 2], b = embree_rate[embree_rate.size() / 2];
      std::printf("%-15s %9zu %11.2f %11.2f %9.2f %9llu %8llu\n", batch.name.c_str(), batch.rays.size(), a, b, a / b,
                  static_cast<unsigned long long>(o.hits), static_cast<unsigned long long>(e.hits));
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pt_embree_side_by_side: %s\n", e.what());
    return 1;
  }
  return 0;
}
