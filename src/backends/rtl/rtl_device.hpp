// The rtl backend's device: the CPU device, except that the wavefront's intersect stage (closest hits and shadow
// rays) runs in the cycle-accurate model of the traversal engine (traversal_engine.v, made into C++ by Verilator):
// the scene's tree and primitives are loaded into the engine's memory, each launch's rays stream through it with
// many in flight, and what it finds goes on through the same kernel functions as on the CPU.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include <fmt/format.h>

#include "backends/cpu/cpu_device.hpp"
#include "flat/flat_scene.hpp"
#include "kernel/fixed_point.hpp"
#include "kernel/wavefront.hpp"

namespace pt {

// What the engine did, per kind of ray: rays, clocks from entering to leaving the engine, and tests issued.
struct EngineTally {
  u64 rays = 0, latency_clocks = 0, box_tests = 0, primitive_tests = 0;
};

struct EngineCounters {
  u64 clocks = 0;  // clocks the engine ran while rays were in it
  u64 box_issues = 0, sphere_issues = 0, triangle_issues = 0, quad_issues = 0, instance_issues = 0, medium_issues = 0;
  EngineTally primary, bounce, shadow;
};

// One query to the engine: a ray and the distance before which hits count.
template <class T>
struct EngineQuery {
  Ray<T> ray;
  T t_max;
  bool shadow;                    // media add their optical depth to it instead of scattering it
  std::array<T, 4> free_flights;  // a path ray's free-flight distance in each medium, in RtlDevice::media_ order
  EngineTally* tally;
};

struct EngineAnswer {
  bool found;
  u32 primitive;
  u32 triangle;                // a mesh triangle's index in MeshData::triangles, else 0
  std::int64_t optical_depth;  // raw: a shadow ray's, summed over the media it crossed
  std::int64_t t, b1, b2;      // raw fixed-point values
};

// Model: the Verilated engine in T's format (Vtraversal_engine_qI_F).
// The CPU device but for its kind, its name, the integrator it prefers and the launches of the intersect stage.
template <class T, class Model>
class RtlDevice : public CpuDevice {
 public:
  static_assert(is_fixed_v<T>, "the traversal engine computes in fixed point");
  static constexpr u32 kWordBits = T::kTotalBits;
  static constexpr u32 kNodeBits = 16, kPrimitiveBits = 16;  // the engine's memories (traversal_engine.v parameters)
  static constexpr std::size_t kMediumSlots = 4;             // free-flight distances a ray brings (traversal_engine.v)

  explicit RtlDevice(unsigned threads) : CpuDevice(threads), model_(std::make_unique<Model>()) {
    model_->reset = 1;
    tick();
    tick();
    model_->reset = 0;
  }

  std::string kind() const { return "rtl"; }
  std::string description() const {
    return fmt::format("traversal engine in Q{}.{}, {} rays in flight, cycle-accurate model; other stages on {}", T::kIntegerBits, T::kFractionBits,
                       model_->context_count, CpuDevice::description());
  }
  Integrator preferred_integrator() const { return Integrator::kWavefront; }

  // The intersect stage's launches go to the engine; every other stage runs on the CPU.
  template <class Kernel>
  void launch(const char* what, u32 count, const Kernel& kernel) {
    if constexpr (std::is_same_v<Kernel, WavefrontIntersect<T>>)
      intersect(kernel.scene, kernel.view, count, 0);
    else if constexpr (std::is_same_v<Kernel, WavefrontIntersectAndShadow<T>>)
      intersect(kernel.scene, kernel.view, kernel.paths, count - kernel.paths);
    else
      CpuDevice::launch(what, count, kernel);
  }

  // Loads the flat scene into the engine's memories (traversal_engine.v): nodes, the scene's then the meshes'; then
  // primitives, the scene's, the meshes' triangles and the media's boundary pieces. A scene it cannot hold is refused.
  void take_scene(const FlatScene<T>& scene) {
    const auto own_nodes = static_cast<u32>(scene.nodes.size()), own_primitives = static_cast<u32>(scene.primitives.size());
    const u64 nodes = u64{own_nodes} + scene.mesh_nodes.size();
    const u64 primitives = u64{own_primitives} + scene.mesh_triangles.size() + scene.boundaries.size();
    if (nodes > (1u << kNodeBits) || primitives > (1u << kPrimitiveBits))
      throw BackendError(fmt::format("the scene has {} BVH nodes and {} primitives and mesh triangles; the traversal engine holds {} of each", nodes,
                                     primitives, 1u << kNodeBits));
    media_.clear();
    for (u32 i = 0; i < own_primitives; ++i)
      if (const auto* medium = std::get_if<ConstantMedium<T>>(&scene.primitives[i].shape)) {
        if (media_.size() == kMediumSlots)
          throw BackendError(
              fmt::format("the scene has more than {} constant media (primitive {}); the traversal engine takes {} free-flight "
                          "distances a ray",
                          kMediumSlots, i, kMediumSlots));
        if (medium->boundary_count == 0) throw BackendError(fmt::format("the constant medium of primitive {} has no boundary", i));
        media_.push_back(MediumSlot{i, *medium});
      }
    node_base_ = own_nodes;
    triangle_base_ = own_primitives;
    const auto boundary_base = static_cast<u32>(own_primitives + scene.mesh_triangles.size());
    node_count_ = nodes;
    primitive_count_ = primitives;
    for (u32 i = 0; i < own_nodes; ++i) load_node(i, scene.nodes[i], 0, 0);
    for (u32 i = 0; i < scene.mesh_nodes.size(); ++i) load_node(node_base_ + i, scene.mesh_nodes[i], node_base_, triangle_base_);
    for (u32 i = 0; i < own_primitives; ++i) {
      std::array<T, 14> fields{};
      u32 kind = std::visit(PrimitiveFields{fields}, scene.primitives[i].shape);
      if (const auto* instance = std::get_if<MeshInstance<T>>(&scene.primitives[i].shape)) {
        kind = 3;
        // The world-to-mesh rows and translation (the identity where the mesh is in world space already: the unit
        // then gives the ray back exactly), and the mesh's root in node memory.
        AffineRows<T> rows{{{T(1), T(0), T(0)}, {T(0), T(1), T(0)}, {T(0), T(0), T(1)}}, {T(0), T(0), T(0)}};
        if (instance->transform != kNoTransform) rows = scene.instance_transforms[instance->transform].to_mesh;
        for (u32 r = 0; r < 3; ++r) PrimitiveFields{fields}.set(3 * r, rows.row[r]);
        PrimitiveFields{fields}.set(9, rows.translation);
        fields[12] = T::from_raw(static_cast<typename T::Storage>(node_base_ + scene.meshes[instance->mesh].root));
      }
      if (const auto* medium = std::get_if<ConstantMedium<T>>(&scene.primitives[i].shape)) {
        // Its pieces' place, their count, its density term, and which of the ray's free-flight distances is its.
        kind = 4;
        fields[0] = T::from_raw(static_cast<typename T::Storage>(boundary_base + medium->first_boundary));
        fields[1] = T::from_raw(static_cast<typename T::Storage>(medium->boundary_count));
        fields[2] = medium->neg_inv_density;
        u32 slot = 0;
        while (media_[slot].primitive != i) ++slot;
        fields[3] = T::from_raw(static_cast<typename T::Storage>(slot));
      }
      load_primitive(i, kind, fields);
    }
    // A mesh's triangles as the scene's are stored: p0 and the two edges from it (the subtraction MeshLeaf makes).
    for (const MeshRecord& record : scene.meshes)
      for (u32 i = record.first_triangle; i < record.first_triangle + record.triangle_count; ++i) {
        const MeshTriangle& tri = scene.mesh_triangles[i];
        const Vec3<T>& p0 = scene.mesh_positions[record.first_vertex + tri.vertex[0]];
        std::array<T, 14> fields{};
        PrimitiveFields{fields}(Triangle<T>{p0, scene.mesh_positions[record.first_vertex + tri.vertex[1]] - p0,
                                            scene.mesh_positions[record.first_vertex + tri.vertex[2]] - p0, -1});
        load_primitive(triangle_base_ + i, 1, fields);
      }
    // The media's boundary pieces: a sphere's two crossings come from the crossings unit (kind 5), a face's from its
    // own unit.
    for (u32 i = 0; i < scene.boundaries.size(); ++i) {
      std::array<T, 14> fields{};
      const Shape<T>& piece = scene.boundaries[i].shape;
      u32 kind = std::visit(PrimitiveFields{fields}, piece);
      if (std::holds_alternative<Sphere<T>>(piece))
        kind = 5;
      else if (!std::holds_alternative<Quad<T>>(piece) && !std::holds_alternative<Triangle<T>>(piece))
        throw BackendError(
            fmt::format("a constant medium's boundary piece {} is neither a sphere, a quad nor a triangle: the traversal engine "
                        "does not hold it",
                        i));
      load_primitive(boundary_base + i, kind, fields);
    }
  }

  // What the engine did since the device was made, as lines for the render's summary.
  std::vector<std::string> report() const {
    const EngineCounters& c = counters_;
    const u64 rays = c.primary.rays + c.bounce.rays + c.shadow.rays;
    std::vector<std::string> lines{
        fmt::format("traversal engine: {} rays in {} clocks, {:.3f} rays a clock; units busy: box (two) {:.1f}%, sphere {:.1f}%, "
                    "triangle {:.1f}%, quad {:.1f}%, instance {:.1f}%, medium {:.1f}%",
                    rays, c.clocks, rays / std::max(1.0, double(c.clocks)), share(c.box_issues) / 2, share(c.sphere_issues), share(c.triangle_issues),
                    share(c.quad_issues), share(c.instance_issues), share(c.medium_issues))};
    for (const auto& [name, tally] : {std::pair{"primary", &c.primary}, std::pair{"bounce", &c.bounce}, std::pair{"shadow", &c.shadow}}) {
      const double n = std::max<double>(1, tally->rays);
      lines.push_back(fmt::format("  {} rays: {}, {:.1f} clocks each in the engine, {:.1f} box and {:.1f} primitive tests each", name, tally->rays,
                                  tally->latency_clocks / n, tally->box_tests / n, tally->primitive_tests / n));
    }
    lines.push_back(fmt::format("  scene memory: {} of {} nodes, {} of {} primitives (mesh triangles and media boundaries included)", node_count_,
                                1u << kNodeBits, primitive_count_, 1u << kPrimitiveBits));
    return lines;
  }

  const EngineCounters& counters() const { return counters_; }

 private:
  void load_node(u32 address, const BvhNode<T>& node, u32 node_offset, u32 primitive_offset) {
    clear_words(model_->node_data);
    const T bounds[6] = {node.lo.x, node.lo.y, node.lo.z, node.hi.x, node.hi.y, node.hi.z};
    for (u32 b = 0; b < 6; ++b) put(model_->node_data, b * kWordBits, kWordBits, raw(bounds[b]));
    put(model_->node_data, 6 * kWordBits, 32, node.left_first + (node.count > 0 ? primitive_offset : node_offset));
    put(model_->node_data, 6 * kWordBits + 32, 32, node.count);
    model_->node_write = 1;
    model_->node_address = address;
    tick();
    model_->node_write = 0;
  }
  void load_primitive(u32 address, u32 kind, const std::array<T, 14>& fields) {
    clear_words(model_->primitive_data);
    for (u32 f = 0; f < fields.size(); ++f) put(model_->primitive_data, f * kWordBits, kWordBits, raw(fields[f]));
    put(model_->primitive_data, 14 * kWordBits, 3, kind);
    model_->primitive_write = 1;
    model_->primitive_address = address;
    tick();
    model_->primitive_write = 0;
  }

  // The engine's kind of each primitive (traversal_engine.v), its 14 fields; spheres go as moving spheres that stand.
  struct PrimitiveFields {
    std::array<T, 14>& f;
    u32 operator()(const Sphere<T>& s) const {
      set(0, s.center);
      f[3] = s.radius;
      return 0;
    }
    u32 operator()(const MovingSphere<T>& s) const {
      set(0, s.center0);
      f[3] = s.radius;
      set(4, s.velocity);
      f[7] = s.time0;
      return 0;
    }
    u32 operator()(const Triangle<T>& t) const {
      set(0, t.p0);
      set(3, t.edge1);
      set(6, t.edge2);
      return 1;
    }
    u32 operator()(const Quad<T>& q) const {
      set(0, q.corner);
      set(3, q.normal);
      set(6, q.du);
      set(9, q.dv);
      f[12] = q.u_extent;
      f[13] = q.v_extent;
      return 2;
    }
    template <class Other>
    u32 operator()(const Other&) const {
      return 3;
    }
    void set(u32 at, const Vec3<T>& v) const {
      f[at] = v.x;
      f[at + 1] = v.y;
      f[at + 2] = v.z;
    }
  };
  static u64 raw(T value) { return static_cast<u64>(static_cast<std::int64_t>(value.raw)); }
  static T from_word(u32 word) {
    const std::int64_t value = static_cast<std::int64_t>(static_cast<u64>(word) << (64 - kWordBits)) >> (64 - kWordBits);
    return T::from_raw(static_cast<typename T::Storage>(value));
  }
  template <class Words>
  static void clear_words(Words& words) {
    std::memset(&words, 0, sizeof words);
  }
  // Sets bits [lsb, lsb + width) of a wide port (Verilator keeps them as 32-bit words, least significant first).
  template <class Words>
  static void put(Words& words, u32 lsb, u32 width, u64 value) {
    for (u32 bit = 0; bit < width; ++bit) {
      const u32 at = lsb + bit;
      const u32 mask = 1u << (at % 32);
      if ((value >> bit) & 1u)
        words[at / 32] |= mask;
      else
        words[at / 32] &= ~mask;
    }
  }
  double share(u64 issues) const { return 100.0 * issues / std::max<u64>(1, counters_.clocks); }

  void tick() {
    model_->clk = 0;
    model_->eval();
    model_->clk = 1;
    model_->eval();
  }

  // The launch's closest-hit queries (paths first, then shadow rays) through the engine, then the rest of the stage.
  void intersect(const SceneView<T>& scene, const WavefrontView<T>& w, u32 paths, u32 shadows) {
    queries_.clear();
    for (u32 i = 0; i < paths; ++i) {
      const PathState<T> path = w.current.load(i);
      // The free-flight distance intersect_medium would draw in each medium (the same draw, from the path's random
      // numbers at this bounce and the medium's index).
      std::array<T, kMediumSlots> free_flights{};
      const SampleRandom random = wavefront_random(scene, w, w.current.item[i]);
      for (std::size_t m = 0; m < media_.size(); ++m)
        free_flights[m] = medium_free_flight(media_[m].medium, media_[m].primitive, random, path.bounce);
      queries_.push_back({path.ray, largest<T>(), false, free_flights, path.bounce == 0 ? &counters_.primary : &counters_.bounce});
    }
    std::vector<ShadowRay<T>> shadow_rays(shadows);
    for (u32 i = 0; i < shadows; ++i) {
      shadow_rays[i] = w.shadows.load(i);
      queries_.push_back({shadow_rays[i].ray, shadow_rays[i].distance, true, {}, &counters_.shadow});
    }
    run(queries_);
    for (u32 i = 0; i < paths + shadows; ++i) {
      const EngineAnswer& a = answers_[i];
      Hit<T> hit{};
      if (a.found) {
        hit.t = T::from_raw(static_cast<typename T::Storage>(a.t));
        hit.b1 = T::from_raw(static_cast<typename T::Storage>(a.b1));
        hit.b2 = T::from_raw(static_cast<typename T::Storage>(a.b2));
        hit.primitive = a.primitive;
        hit.triangle = a.triangle;
      }
      if (i < paths)
        wavefront_queue_hit(w, scene, i, a.found, hit);
      else
        wavefront_add_shadow(
            w, i - paths,
            shadow_contribution_found(scene, shadow_rays[i - paths], a.found, hit, T::from_raw(static_cast<typename T::Storage>(a.optical_depth))));
    }
  }

  // Streams the queries through the engine, one offered a clock, until every answer is back.
  void run(const std::vector<EngineQuery<T>>& queries) {
    answers_.assign(queries.size(), EngineAnswer{});
    entered_.assign(queries.size(), 0);
    Model& m = *model_;
    std::size_t next = 0, back = 0;
    while (back < queries.size()) {
      m.ray_valid = next < queries.size();
      if (m.ray_valid) {
        const EngineQuery<T>& q = queries[next];
        m.ray_id = static_cast<u32>(next);
        m.origin_x = static_cast<u32>(raw(q.ray.origin.x));
        m.origin_y = static_cast<u32>(raw(q.ray.origin.y));
        m.origin_z = static_cast<u32>(raw(q.ray.origin.z));
        m.direction_x = static_cast<u32>(raw(q.ray.direction.x));
        m.direction_y = static_cast<u32>(raw(q.ray.direction.y));
        m.direction_z = static_cast<u32>(raw(q.ray.direction.z));
        m.ray_time = static_cast<u32>(raw(q.ray.time));
        m.t_max = static_cast<u32>(raw(q.t_max));
        m.ray_shadow = q.shadow;
        m.medium_distance_0 = static_cast<u32>(raw(q.free_flights[0]));
        m.medium_distance_1 = static_cast<u32>(raw(q.free_flights[1]));
        m.medium_distance_2 = static_cast<u32>(raw(q.free_flights[2]));
        m.medium_distance_3 = static_cast<u32>(raw(q.free_flights[3]));
      }
      m.clk = 0;
      m.eval();
      const bool accepted = m.ray_valid && m.ray_ready;
      counters_.box_issues += m.box_issue + m.second_box_issue;
      counters_.sphere_issues += m.sphere_issue;
      counters_.triangle_issues += m.triangle_issue;
      counters_.quad_issues += m.quad_issue;
      counters_.instance_issues += m.instance_issue;
      counters_.medium_issues += m.medium_issue;
      m.clk = 1;
      m.eval();
      ++counters_.clocks;
      if (accepted) entered_[next++] = counters_.clocks;
      if (m.hit_valid) {
        const u32 id = m.hit_id;
        answers_[id] = EngineAnswer{m.hit_found != 0,
                                    m.hit_primitive,
                                    m.hit_in_mesh ? m.hit_triangle - triangle_base_ : 0u,
                                    from_word(m.hit_optical_depth).raw,
                                    from_word(m.hit_t).raw,
                                    from_word(m.hit_b1).raw,
                                    from_word(m.hit_b2).raw};
        EngineTally& tally = *queries[id].tally;
        ++tally.rays;
        tally.latency_clocks += counters_.clocks - entered_[id];
        tally.box_tests += m.hit_box_tests;
        tally.primitive_tests += m.hit_primitive_tests;
        ++back;
      }
    }
    m.ray_valid = 0;
  }

  std::unique_ptr<Model> model_;
  u32 node_base_ = 0, triangle_base_ = 0;     // where the meshes' nodes and triangles begin in the engine's memories
  u64 node_count_ = 0, primitive_count_ = 0;  // the scene's share of them
  struct MediumSlot {
    u32 primitive;
    ConstantMedium<T> medium;
  };
  std::vector<MediumSlot> media_;  // the scene's media, in the order of the free-flight distances a ray brings
  EngineCounters counters_;
  std::vector<EngineQuery<T>> queries_;
  std::vector<EngineAnswer> answers_;
  std::vector<u64> entered_;
};

}  // namespace pt
