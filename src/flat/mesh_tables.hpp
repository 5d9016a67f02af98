// The meshes of a flat scene: each placement of a model file's mesh built with its BVH (in world space, or once in
// its own space where it is placed several times), then converted into the kernels' mesh arrays.
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "flat/bvh_builder.hpp"
#include "flat/fit.hpp"
#include "flat/flat_scene.hpp"
#include "flat/wide_bvh_builder.hpp"
#include "scene/mesh.hpp"

namespace pt {

// Each placement of a model file's mesh becomes an instance primitive. A mesh placed once is stored in world space
// (its instance has no transform, so rays are not transformed for it); a mesh placed more often is stored once in its
// own space with one BVH, and each instance carries the affine map into and out of that space.

// A placement met while reading the objects; `primitive` is its instance's index in the primitive list.
struct MeshPlacementUse {
  u32 file, mesh;
  AffineTransform transform;  // mesh space to world
  u32 object;
};

// A mesh as the kernels will store it, before conversion to their scalar type: triangles (local vertex indices,
// scene materials) in BVH order and its BVH over them. Vertices, normals and texture coordinates are not copied:
// they are read from the file's mesh, mapped by `placed`, when converted.
struct MeshBuild {
  u32 object;         // the first object placing it, for messages
  std::string name;   // the file's name for it
  std::string where;  // the JSON path of the object placing it, for messages (none for a model given as the scene)
  const TriangleMesh* source = nullptr;
  AffineTransform placed;  // mesh space to the space the mesh is stored in (the identity for a shared mesh)
  bool identity = true;    // placed is the identity
  bool has_normals = false, has_uvs = false;
  bool has_tangents = false;  // the file's vertex tangents, kept where a triangle's material has a normal map
  double scale = 1;           // flatten_scene's scale, applied to lengths as they are converted
  std::vector<MeshTriangle> triangles;
  // Float boxes where the mesh's coordinates fit float (half the memory of double; exact corners for float
  // vertices, rounded outward otherwise), double boxes beyond.
  std::variant<BuiltBvh<float>, BuiltBvh<double>> bvh;

  Vec3d position(u32 v) const { return identity ? source->positions[v] : placed.apply_point(source->positions[v]); }
  // A tangent is a vector along the surface: it goes by the map itself (normals by its inverse transpose).
  Vec3d tangent(u32 v) const {
    const std::array<double, 4>& t = source->tangents[v];
    return identity ? Vec3d{t[0], t[1], t[2]} : placed.apply_vector(Vec3d{t[0], t[1], t[2]});
  }
  Vec3d normal(u32 v) const {
    const Vec3d turned = identity ? source->normals[v] : placed.apply_normal(source->normals[v]);
    const double length_squared_n = length_squared(turned);
    return length_squared_n > 0 ? turned / std::sqrt(length_squared_n) : Vec3d{0, 0, 0};
  }
  // The root's box, in double, before scaling.
  Aabb root() const {
    return std::visit([](const auto& b) { return scaled_box(b.nodes[0], 1); }, bvh);
  }
};

// The mesh of a placement with its vertices mapped by `placed`, its degenerate triangles dropped and its BVH built.
MeshBuild build_mesh(const SceneDescription& scene, const MeshPlacementUse& use, const AffineTransform& placed);

// The box of a mesh's BVH root mapped by an affine map: the box of its eight mapped corners.
Aabb mapped_box(const Aabb& root, const AffineTransform& map);

// The meshes' arrays of `flat` and the instances' maps, in the kernels' type; each mesh's own arrays are freed as
// they are converted.
template <class T>
void flatten_meshes(const Fit<T>& fit, std::vector<MeshBuild>& meshes, const std::vector<AffineTransform>& maps, const std::vector<u32>& map_objects,
                    FlatScene<T>& flat);

}  // namespace pt
