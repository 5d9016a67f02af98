// The meshes of a flat scene: built per placement, then converted into the kernels' arrays (mesh_tables.hpp).
#include "flat/mesh_tables.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>

#include "base/free_memory.hpp"
#include "base/scalar_types.hpp"
#include "flat/duplicates.hpp"

namespace pt {

// The mesh with its vertices mapped by `placed` (the identity for a shared mesh, kept in its own space), triangles
// with zero area dropped (they can never be hit), and its BVH built.
namespace {

// Which of a mesh's triangles to draw: all but exact copies of an earlier one, with the same corners in the same turn
// (from any of the three) and the same material; where vertices carry normals, uvs or tangents, the same vertices.
std::vector<char> distinct_triangles(const TriangleMesh& mesh, bool vertices_matter) {
  const auto less = [&](u32 a, u32 b) {
    if (vertices_matter) return a < b;
    const Vec3d &p = mesh.positions[a], &q = mesh.positions[b];
    return p.x != q.x ? p.x < q.x : p.y != q.y ? p.y < q.y : p.z < q.z;
  };
  // The corners turned to start from the least (equal corners make a triangle without area, never drawn).
  const auto turned = [&](std::size_t t) {
    const std::array<u32, 3>& v = mesh.triangles[t];
    const int first = less(v[1], v[0]) ? (less(v[2], v[1]) ? 2 : 1) : (less(v[2], v[0]) ? 2 : 0);
    return std::array<u32, 3>{v[first], v[(first + 1) % 3], v[(first + 2) % 3]};
  };
  const auto material = [&](std::size_t t) { return mesh.materials.empty() ? 0u : mesh.materials[t]; };
  return first_of_each(
      mesh.triangles.size(),
      [&](std::size_t t) {
        BitHash hash;
        hash.add_bits(material(t));
        for (const u32 v : turned(t)) {
          const Vec3d& p = mesh.positions[v];
          hash.add(p.x), hash.add(p.y), hash.add(p.z);
          if (vertices_matter) hash.add_bits(v);
        }
        return hash.value();
      },
      [&](std::size_t s, std::size_t t) {
        if (material(s) != material(t)) return false;
        const std::array<u32, 3> a = turned(s), b = turned(t);
        for (int k = 0; k < 3; ++k) {
          const Vec3d &p = mesh.positions[a[k]], &q = mesh.positions[b[k]];
          if (p.x != q.x || p.y != q.y || p.z != q.z || (vertices_matter && a[k] != b[k])) return false;
        }
        return true;
      });
}

}  // namespace

MeshBuild build_mesh(const SceneDescription& scene, const MeshPlacementUse& use, const AffineTransform& placed) {
  const SceneMeshFile& entry = scene.mesh_files[use.file];
  const TriangleMesh& mesh = entry.file->meshes[use.mesh];
  MeshBuild out;
  out.object = use.object;
  out.name = mesh.name;
  out.where = scene.model_as_scene ? "" : "/objects/" + std::to_string(use.object) + "/file";
  out.source = &mesh;
  out.placed = placed;
  out.identity = placed.is_identity();
  out.has_normals = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
  out.has_uvs = mesh.uvs.size() == mesh.positions.size() && !mesh.uvs.empty();
  const bool file_tangents = out.has_normals && mesh.tangents.size() == mesh.positions.size();
  // The mapped vertices, for the build only (freed when it returns).
  std::vector<Vec3d> mapped;
  if (!out.identity) {
    mapped.reserve(mesh.positions.size());
    for (const Vec3d& p : mesh.positions) mapped.push_back(placed.apply_point(p));
  }
  const std::vector<Vec3d>& positions = out.identity ? mesh.positions : mapped;
  double largest_coordinate = 0;
  for (const Vec3d& p : positions) largest_coordinate = std::max({largest_coordinate, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const bool float_boxes = float_box_fits(largest_coordinate);
  // A mirroring map turns the winding around: swap two vertices so that the front stays the front.
  const bool mirrored = placed.determinant() < 0;
  std::vector<FloatBox> float_bounds;
  std::vector<Aabb> bounds;
  out.triangles.reserve(mesh.triangles.size());
  if (float_boxes)
    float_bounds.reserve(mesh.triangles.size());
  else
    bounds.reserve(mesh.triangles.size());
  const std::vector<char> keep = distinct_triangles(mesh, out.has_normals || out.has_uvs || file_tangents);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const std::array<u32, 3>& v = mesh.triangles[t];
    const Vec3d& a = positions[v[0]];
    const Vec3d& b = positions[v[1]];
    const Vec3d& c = positions[v[2]];
    if (length_squared(cross(b - a, c - a)) == 0 || !keep[t]) continue;
    const u32 file_material = mesh.materials.empty() ? 0 : mesh.materials[t];
    const u32 material = file_material < entry.materials.size() ? entry.materials[file_material] : entry.materials.at(0);
    out.triangles.push_back(mirrored ? MeshTriangle{{v[0], v[2], v[1]}, material} : MeshTriangle{{v[0], v[1], v[2]}, material});
    if (file_tangents && !out.has_tangents) {
      const auto* m = std::get_if<MetallicRoughness<double>>(&scene.materials[material]);
      out.has_tangents = m && m->normal_map != kNoNormalMap;
    }
    Aabb box;
    box.grow(a);
    box.grow(b);
    box.grow(c);
    if (float_boxes)
      float_bounds.push_back(outward_float_box(box));
    else
      bounds.push_back(box);
  }
  std::vector<Vec3d>().swap(mapped);
  std::vector<u32> order;
  if (float_boxes) {
    BuiltBvh<float> built = build_bvh(float_bounds);
    std::vector<FloatBox>().swap(float_bounds);
    order = std::move(built.order);
    out.bvh = std::move(built);
  } else {
    BuiltBvh<double> built = build_bvh(bounds);
    std::vector<Aabb>().swap(bounds);
    order = std::move(built.order);
    out.bvh = std::move(built);
  }
  {
    std::vector<MeshTriangle> ordered;
    ordered.reserve(out.triangles.size());
    for (u32 i : order) ordered.push_back(out.triangles[i]);
    out.triangles = std::move(ordered);
  }
  std::vector<u32>().swap(order);
  release_free_memory();  // the boxes, the order and the unordered triangles
  return out;
}

// The box of a mesh's BVH root mapped by an affine map: the box of its eight mapped corners.
Aabb mapped_box(const Aabb& root, const AffineTransform& map) {
  Aabb box;
  for (int corner = 0; corner < 8; ++corner)
    box.grow(map.apply_point(Vec3d{corner & 1 ? root.hi.x : root.lo.x, corner & 2 ? root.hi.y : root.lo.y, corner & 4 ? root.hi.z : root.lo.z}));
  return box;
}

// Appends `from` to `to` and frees it; where `to` has no storage yet (one mesh), it takes the array over instead.
template <class A>
void append_and_free(A& to, A& from) {
  if (to.capacity() == 0)
    to = std::move(from);
  else
    to.insert(to.end(), from.begin(), from.end());
  A().swap(from);
}

// The meshes' arrays in the kernels' type: vertices checked as lengths (a mesh's extent stands for its triangles'
// edges), normals and texture coordinates as plain values, the BVHs padded and their indices made global, and the
// instances' maps with their inverses and the normals' inverse transpose. Each mesh's own arrays are freed as soon
// as they are converted, so that the peak of memory stays near the result's size.
template <class T>
void flatten_meshes(const Fit<T>& fit, std::vector<MeshBuild>& meshes, const std::vector<AffineTransform>& maps, const std::vector<u32>& map_objects,
                    FlatScene<T>& flat) {
  std::size_t vertices = 0, normals = 0, uvs = 0, tangents = 0;
  for (const MeshBuild& m : meshes) {
    vertices += m.source->positions.size();
    normals += m.has_normals ? m.source->positions.size() : 0;
    uvs += m.has_uvs ? m.source->positions.size() : 0;
    tangents += m.has_tangents ? m.source->positions.size() : 0;
  }
  flat.mesh_positions.reserve(vertices);
  flat.mesh_normals.reserve(normals);
  flat.mesh_uvs.reserve(uvs);
  flat.mesh_tangents.reserve(tangents);
  if (meshes.size() > 1) {  // one mesh's arrays are taken over (append_and_free)
    std::size_t triangles = 0, nodes = 0;
    for (const MeshBuild& m : meshes) {
      triangles += m.triangles.size();
      nodes += std::visit([](const auto& b) { return b.nodes.size(); }, m.bvh);
    }
    flat.mesh_triangles.reserve(triangles);
    flat.mesh_nodes.reserve(nodes);
  }
  for (MeshBuild& m : meshes) {
    const std::string& where = m.where;
    const std::string vertex = fmt::format("a vertex of mesh '{}'", m.name);
    const double scale = m.scale;
    const u32 vertex_count = static_cast<u32>(m.source->positions.size());
    MeshRecord record{};
    record.first_vertex = static_cast<u32>(flat.mesh_positions.size());
    for (u32 v = 0; v < vertex_count; ++v) {
      Vec3d p = m.position(v);
      if (scale != 1) p = p * scale;
      flat.mesh_positions.push_back(fit(p, Quantity::kLength, where, vertex));
    }
    const Aabb root = m.root();
    fit(root.hi * scale - root.lo * scale, Quantity::kTriangleEdge, where, fmt::format("the extent of mesh '{}', which bounds its edges", m.name));
    record.first_normal = kNoAttributes;
    if (m.has_normals) {
      record.first_normal = static_cast<u32>(flat.mesh_normals.size());
      for (u32 v = 0; v < vertex_count; ++v) flat.mesh_normals.push_back(fit(m.normal(v), Quantity::kPlain, where, "a vertex normal"));
    }
    record.first_uv = kNoAttributes;
    if (m.has_uvs) {
      record.first_uv = static_cast<u32>(flat.mesh_uvs.size());
      for (const auto& uv : m.source->uvs)
        flat.mesh_uvs.push_back(
            MeshUv<T>{fit(uv[0], Quantity::kPlain, where, "a texture coordinate"), fit(uv[1], Quantity::kPlain, where, "a texture coordinate")});
    }
    record.first_tangent = kNoAttributes;
    if (m.has_tangents) {
      // Unit length, so that a placement's scale cannot take them out of the type's range (only directions count).
      // The bitangent is sign * normal x tangent: a mirroring placement maps the tangent and the bitangent as
      // vectors but keeps the normal outward, so the sign turns with it.
      record.first_tangent = static_cast<u32>(flat.mesh_tangents.size());
      const double mirror = m.placed.determinant() < 0 ? -1.0 : 1.0;
      for (u32 v = 0; v < vertex_count; ++v) {
        const Vec3d t = m.tangent(v);
        const double norm = length(t);
        flat.mesh_tangents.push_back(
            MeshTangent<T>{fit(norm > 0 && std::isfinite(norm) ? t / norm : Vec3d{}, Quantity::kPlain, where, "a vertex tangent"),
                           fit(m.source->tangents[v][3] < 0 ? -mirror : mirror, Quantity::kPlain, where, "a vertex tangent")});
      }
    }
    record.first_triangle = static_cast<u32>(flat.mesh_triangles.size());
    record.triangle_count = static_cast<u32>(m.triangles.size());
    append_and_free(flat.mesh_triangles, m.triangles);
    record.root = static_cast<u32>(flat.mesh_nodes.size());
    record.wide_root = static_cast<u32>(flat.mesh_wide_nodes.size());
    std::visit(
        [&]<class S>(BuiltBvh<S>& bvh) {
          // The wide tree first, while the binary nodes are still as built; then the binary nodes, converted in
          // place where the kernels' nodes are the built ones' type.
          std::vector<WideBvhNode<T>> wide = build_wide_bvh<T, S>(bvh.nodes, scale);
          for (WideBvhNode<T>& w : wide)
            for (u32 lane = 0; lane < kWideBvhWidth; ++lane) {
              if (w.leaf_mask & (1u << lane)) w.child[lane] += record.first_triangle;
              if (w.inner_mask & (1u << lane)) w.child[lane] += record.wide_root;
            }
          append_and_free(flat.mesh_wide_nodes, wide);
          auto global = [&](const BvhNode<S>& n) {
            BvhNode<T> out = padded_node<T>(n, scale);
            out.left_first += n.count > 0 ? record.first_triangle : record.root;
            return out;
          };
          if constexpr (std::is_same_v<S, T>) {
            for (BvhNode<S>& n : bvh.nodes) n = global(n);
            append_and_free(flat.mesh_nodes, bvh.nodes);
          } else {
            if (flat.mesh_nodes.capacity() == 0) flat.mesh_nodes.reserve(bvh.nodes.size());
            for (const BvhNode<S>& n : bvh.nodes) flat.mesh_nodes.push_back(global(n));
            std::vector<BvhNode<S>>().swap(bvh.nodes);
          }
        },
        m.bvh);
    flat.meshes.push_back(record);
  }
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const std::string where = "/objects/" + std::to_string(map_objects[i]) + "/transform";
    const AffineTransform& to_world = maps[i];
    const AffineTransform to_mesh = to_world.inverse();
    auto rows = [&](const AffineTransform& a) {
      AffineRows<T> out;
      for (int r = 0; r < 3; ++r)
        out.row[r] = fit(Vec3d{a.linear[r][0], a.linear[r][1], a.linear[r][2]}, Quantity::kPlain, where, "the map placing a mesh");
      out.translation = fit(a.translation, Quantity::kLength, where, "the map placing a mesh");
      return out;
    };
    InstanceTransform<T> out;
    out.to_world = rows(to_world);
    out.to_mesh = rows(to_mesh);
    // Normals go by the inverse transpose: row r is column r of the inverse.
    for (int r = 0; r < 3; ++r)
      out.normal_rows[r] =
          fit(Vec3d{to_mesh.linear[0][r], to_mesh.linear[1][r], to_mesh.linear[2][r]}, Quantity::kPlain, where, "the map placing a mesh");
    flat.instance_transforms.push_back(out);
  }
}

#define PT_INSTANTIATE_MESH_TABLES(...)                                                                                            \
  template void flatten_meshes<__VA_ARGS__>(const Fit<__VA_ARGS__>&, std::vector<MeshBuild>&, const std::vector<AffineTransform>&, \
                                            const std::vector<u32>&, FlatScene<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_MESH_TABLES)

}  // namespace pt
