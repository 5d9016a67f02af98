// Records the operand sets one intersection unit receives in real renders of scenes, in a fixed-point format or in
// float32, and writes them to stdout for the unit's Verilator testbench:
//
//   pt_record_operands --unit box --format q16.16 --count 1000000 scenes/cornell-box.json scenes/tiny.json ...
//   pt_record_operands --unit box --format float32 ...
//
// Paths are traced by the kernel's own functions (start_path, path_shade and its shadow rays, as trace_sample does),
// with the closest-hit query walking the binary BVH as GPUs do (walk_binary, SceneLeaf, MeshLeaf) so that each box
// test and each primitive test can be recorded with the very operands the kernel function is called with. The
// count is shared among the scenes that have the unit's primitive, each tracing at most --max-samples samples per
// pixel but the last, which makes up the rest; pixels are visited in a scattered order, so that a scene's share
// covers the whole image.
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "base/number_formats.hpp"
#include "flat/flat_scene.hpp"
#include "hardware/operands.hpp"
#include "loading/scene_loader.hpp"
#include "recorded_formats.hpp"  // generated: PT_FOR_EACH_RECORDED_FORMAT

namespace pt::hardware {
namespace {

enum class UnitKind { kBox, kTriangle, kQuad, kSphere };

UnitKind unit_kind(const std::string& name) {
  if (name == "box") return UnitKind::kBox;
  if (name == "triangle") return UnitKind::kTriangle;
  if (name == "quad") return UnitKind::kQuad;
  if (name == "sphere") return UnitKind::kSphere;
  throw std::runtime_error("unknown unit '" + name + "' (box, triangle, quad, sphere)");
}

int value_count(UnitKind kind) {
  switch (kind) {
    case UnitKind::kBox: return static_cast<int>(BoxOperands::kInputs.size());
    case UnitKind::kTriangle: return static_cast<int>(TriangleOperands::kInputs.size());
    case UnitKind::kQuad: return static_cast<int>(QuadOperands::kInputs.size());
    default: return static_cast<int>(SphereOperands::kInputs.size());
  }
}

// Buffers operand sets and writes them out; counts what this scene contributed.
class Sink {
 public:
  Sink(UnitKind kind, std::FILE* out) : kind_(kind), values_(value_count(kind)), out_(out) {}
  UnitKind kind() const { return kind_; }
  i64* next() {
    if (buffer_.size() + values_ > kFlushValues) flush();
    buffer_.resize(buffer_.size() + values_);
    ++recorded_;
    return buffer_.data() + buffer_.size() - values_;
  }
  void flush() {
    if (!buffer_.empty() && std::fwrite(buffer_.data(), sizeof(i64), buffer_.size(), out_) != buffer_.size())
      throw std::runtime_error("cannot write the operand stream");
    buffer_.clear();
  }
  std::size_t recorded() const { return recorded_; }

 private:
  static constexpr std::size_t kFlushValues = 1 << 16;
  UnitKind kind_;
  std::size_t values_;
  std::FILE* out_;
  std::vector<i64> buffer_;
  std::size_t recorded_ = 0;
};

// The kernel's walk of the binary tree (walk_binary, src/kernel/bvh.hpp) with each box test recorded before it is made.
template <class T>
struct BoxRecorder {
  Sink& sink;
  void box_test(const BvhNode<T>& node, const BoxRay<T>& box_ray, T t_min, T closest) const {
    if (sink.kind() == UnitKind::kBox) BoxOperands::pack(box_ray, node, t_min, closest, sink.next());
  }
  bool keep_walking() const { return true; }
};

// MeshLeaf with each triangle test recorded.
template <class T>
struct RecordedMeshLeaf {
  const MeshData<T>& meshes;
  u32 first_vertex;
  const Ray<T>& ray;
  Hit<T>& hit;
  Sink& sink;
  bool operator()(u32 first, u32 count, T& closest) const {
    bool found = false;
    for (u32 i = first; i < first + count; ++i) {
      const MeshTriangle& tri = meshes.triangles[i];
      const Vec3<T>& p0 = meshes.positions[first_vertex + tri.vertex[0]];
      const Triangle<T> triangle{p0, meshes.positions[first_vertex + tri.vertex[1]] - p0, meshes.positions[first_vertex + tri.vertex[2]] - p0, -1};
      if (sink.kind() == UnitKind::kTriangle) TriangleOperands::pack(triangle, ray, hit_distance_min<T>(), closest, sink.next());
      Hit<T> candidate;
      if (intersect_triangle(triangle, ray, hit_distance_min<T>(), closest, candidate)) {
        closest = candidate.t;
        hit.t = candidate.t;
        hit.b1 = candidate.b1;
        hit.b2 = candidate.b2;
        hit.triangle = i;
        found = true;
      }
    }
    return found;
  }
};

// The geometric tests intersect_geometry makes for a shape, recorded (media boundaries included: their quads are
// tested over the whole line, their spheres go through sphere_roots alone, which is not a unit of its own).
template <class T>
void record_shape(const Shape<T>& shape, const Ray<T>& ray, T t_min, T t_max, Sink& sink) {
  if (const auto* s = std::get_if<Sphere<T>>(&shape)) {
    if (sink.kind() == UnitKind::kSphere) SphereOperands::pack(s->center, s->radius, ray, t_min, t_max, sink.next());
  } else if (const auto* m = std::get_if<MovingSphere<T>>(&shape)) {
    if (sink.kind() == UnitKind::kSphere) SphereOperands::pack(moving_sphere_center(*m, ray.time), m->radius, ray, t_min, t_max, sink.next());
  } else if (const auto* tri = std::get_if<Triangle<T>>(&shape)) {
    if (sink.kind() == UnitKind::kTriangle) TriangleOperands::pack(*tri, ray, t_min, t_max, sink.next());
  } else if (const auto* q = std::get_if<Quad<T>>(&shape)) {
    if (sink.kind() == UnitKind::kQuad) QuadOperands::pack(*q, ray, t_min, t_max, sink.next());
  }
}

// SceneLeaf with each primitive test recorded.
template <class T>
struct RecordedSceneLeaf {
  const SceneView<T>& scene;
  const Ray<T>& ray;
  const IntersectContext<T>& context;
  Hit<T>& hit;
  Sink& sink;
  bool operator()(u32 first, u32 count, T& closest) const {
    bool found = false;
    for (u32 i = first; i < first + count; ++i) {
      const Primitive<T>& primitive = scene.primitives[i];
      if (const auto* instance = std::get_if<MeshInstance<T>>(&primitive.shape)) {
        const Ray<T> local = instance_ray(scene.meshes, *instance, ray);
        const MeshRecord& mesh = scene.meshes.meshes[instance->mesh];
        RecordedMeshLeaf<T> leaf{scene.meshes, mesh.first_vertex, local, hit, sink};
        if (walk_binary(scene.meshes.nodes, mesh.root, make_box_ray(local), closest, leaf, BoxRecorder<T>{sink})) {
          hit.primitive = i;
          found = true;
        }
        continue;
      }
      if (const auto* medium = std::get_if<ConstantMedium<T>>(&primitive.shape)) {
        for (u32 b = 0; b < medium->boundary_count; ++b)
          record_shape(context.boundaries[medium->first_boundary + b].shape, ray, -largest<T>(), largest<T>(), sink);
      } else {
        record_shape(primitive.shape, ray, hit_distance_min<T>(), closest, sink);
      }
      Hit<T> candidate;
      if (intersect_primitive(primitive, i, context, ray, hit_distance_min<T>(), closest, candidate)) {
        closest = candidate.t;
        hit = candidate;
        hit.primitive = i;
        found = true;
      }
    }
    return found;
  }
};

template <class T>
bool recorded_closest_hit(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit, T t_max, Sink& sink) {
  T closest = t_max;
  RecordedSceneLeaf<T> leaf{scene, ray, context, hit, sink};
  return walk_binary(scene.nodes, 0u, make_box_ray(ray), closest, leaf, BoxRecorder<T>{sink});
}

// Traces paths of one scene until `quota` operand sets are recorded or `max_samples` samples of every pixel are done.
template <class T>
std::size_t record_scene(const FlatScene<T>& flat, std::size_t quota, u32 max_samples, Sink& sink) {
  const SceneView<T> scene = flat.view();
  const u32 width = scene.params.width, height = scene.params.height, pixels = width * height;
  const std::size_t before = sink.recorded();
  // Visiting pixels with a stride coprime to their count spreads the recorded rays over the image.
  u32 stride = 7919;
  while (pixels % stride == 0) stride += 2;
  for (u32 sample = 0; sample < max_samples; ++sample) {
    for (u32 k = 0; k < pixels; ++k) {
      if (sink.recorded() - before >= quota) return sink.recorded() - before;
      const u32 pixel = static_cast<u32>((static_cast<u64>(k) * stride) % pixels);
      const u32 x = pixel % width, y = pixel / width;
      const SampleRandom random = path_random(scene.params, pixel, sample);
      PathState<T> path = start_path(scene, x, y, random);
      while (path.bounce < scene.params.max_depth) {
        Hit<T> hit{};
        if (!recorded_closest_hit(scene, path.ray, IntersectContext<T>{scene.boundaries, &random, path.bounce}, hit, largest<T>(), sink)) break;
        ShadowRay<T> shadow;
        const bool goes_on = path_shade(scene, path, hit, random, shadow);
        if (shadow.entry != kNoLight) {
          Hit<T> shadow_hit{};
          T optical_depth = T(0);
          recorded_closest_hit(scene, shadow.ray, IntersectContext<T>{scene.boundaries, &random, 0, &optical_depth}, shadow_hit, shadow.distance,
                               sink);
        }
        if (!goes_on) break;
      }
    }
  }
  return sink.recorded() - before;
}

int run(int argc, char** argv) {
  std::string unit, format;
  std::size_t count = 1000000;
  u32 width = 160, height = 120, max_samples = 16;
  std::vector<std::string> scenes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--unit")
      unit = next();
    else if (arg == "--format")
      format = next();
    else if (arg == "--count")
      count = std::stoull(next());
    else if (arg == "--width")
      width = static_cast<u32>(std::stoul(next()));
    else if (arg == "--height")
      height = static_cast<u32>(std::stoul(next()));
    else if (arg == "--max-samples")
      max_samples = static_cast<u32>(std::stoul(next()));
    else
      scenes.push_back(arg);
  }
  if (unit.empty() || format.empty() || scenes.empty())
    throw std::runtime_error("usage: pt_record_operands --unit box|triangle|quad|sphere --format qI.F [--count N] SCENE...");
  const UnitKind kind = unit_kind(unit);
  Sink sink(kind, stdout);
  // Only the formats the units are tested in (PT_FOR_EACH_RECORDED_FORMAT, from PT_HARDWARE_FORMATS): each one
  // compiles the path tracer's kernels once more.
  auto record = [&]<class T>() -> int {
    {
      StreamHeader header{};
      std::memcpy(header.magic, kStreamMagic, sizeof header.magic);
      std::snprintf(header.unit, sizeof header.unit, "%s", unit.c_str());
      // float32 is written as q0.0.
      if constexpr (is_fixed_v<T>) {
        header.integer_bits = T::kIntegerBits;
        header.fraction_bits = T::kFractionBits;
      }
      header.values = value_count(kind);
      std::fwrite(&header, sizeof header, 1, stdout);
      for (std::size_t s = 0; s < scenes.size(); ++s) {
        const SceneDescription description = load_scene_file(scenes[s]);
        RenderSettings settings = description.render;
        settings.width = width;
        settings.height = height;
        FlatScene<T> flat;
        try {
          flat = flatten_scene<T>(description, settings, 0);
        } catch (const InputError& e) {
          std::fprintf(stderr, "%s: skipped, it does not fit %s: %s\n", scenes[s].c_str(), format.c_str(), e.what());
          continue;
        }
        // What is still missing, shared equally among the scenes still to come.
        const std::size_t quota = (count - std::min(count, sink.recorded()) + (scenes.size() - s) - 1) / (scenes.size() - s);
        // The last scene makes up what the others could not give in their samples.
        const u32 samples = s + 1 == scenes.size() ? 1024 : max_samples;
        const std::size_t got = record_scene(flat, quota, samples, sink);
        std::fprintf(stderr, "%s: %zu %s operand sets (scale %g)\n", scenes[s].c_str(), got, unit.c_str(), flat.scale);
      }
      sink.flush();
      std::fflush(stdout);
      std::fprintf(stderr, "recorded %zu %s operand sets in %s\n", sink.recorded(), unit.c_str(), format.c_str());
      return 0;
    }
  };
#define PT_RECORD_IN(integer, fraction) \
  if (format == number_format_name<Fixed<integer, fraction>>()) return record.template operator()<Fixed<integer, fraction>>();
  PT_FOR_EACH_RECORDED_FORMAT(PT_RECORD_IN)
#undef PT_RECORD_IN
#if PT_RECORD_FLOAT32
  // The renderer's float code path as the host runs it (FTZ and DAZ off): the recording only gives operands, and the
  // testbench feeds the same recorded bits to the unit and to the model, which it runs with the unit's policy.
  if (format == "float32") return record.template operator()<float>();
#endif
  throw std::runtime_error("format " + format + " is not among those recorded (PT_HARDWARE_FORMATS, PT_HARDWARE_FLOAT32_UNITS)");
}

}  // namespace
}  // namespace pt::hardware

int main(int argc, char** argv) {
  try {
    return pt::hardware::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pt_record_operands: %s\n", e.what());
    return 1;
  }
}
