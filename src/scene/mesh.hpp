// Triangle meshes of the parsed scene, as read from model files (Wavefront OBJ, PLY, glTF 2.0; loading/model_files.hpp):
// indexed vertex arrays, materials and textures in double precision on the host, before a scene places them and
// flattening turns them into the kernels' arrays.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "image/image_io.hpp"
#include "scene/scene.hpp"

namespace pt {

// What a model file says about a surface, in the terms every format shares (glTF's metallic-roughness model; OBJ's
// Kd/Ke/map_Kd/Pm/Pr/Ks/Ns map onto it). Colours are linear RGB; a factor multiplies its texture where there is one.
struct MeshMaterial {
  std::string name;
  Vec3d base_color{0.8, 0.8, 0.8};
  i32 base_color_texture = -1;  // index into MeshFile::textures, or -1
  Vec3d emission{0, 0, 0};      // emitted radiance
  i32 emission_texture = -1;
  double metallic = 0, roughness = 1;
  i32 metallic_roughness_texture = -1;  // glTF's: roughness in green, metallic in blue, linear bytes; or -1
  i32 normal_texture = -1;              // a tangent-space normal map (linear bytes, +Y up), or -1
  double normal_scale = 1;              // multiplies the normal map's x and y
  // Whether the surface is shaded with the metallic-roughness model (glTF always; OBJ where its MTL says anything
  // about metal, roughness or specular highlights), or as a plain diffuse reflector of the base colour (files that
  // only give a colour: PLY, OBJ with Kd alone), as they were before the model existed.
  bool metallic_roughness_model = false;
};

// One indexed triangle mesh. A vertex is one index into every per-vertex array (formats that index positions,
// normals and uvs separately, like OBJ, are unified by the reader).
struct TriangleMesh {
  std::string name;  // for messages: the file's name for it, or "mesh N"
  std::vector<Vec3d> positions;
  std::vector<Vec3d> normals;                   // empty, or one per position (unit length)
  std::vector<std::array<double, 2>> uvs;       // empty, or one per position (v up, as OBJ and PLY write it)
  std::vector<std::array<double, 4>> tangents;  // empty, or one per position where there are normals: glTF's TANGENT,
                                                // xyz along increasing u, w the bitangent's sign (w normal x xyz)
  std::vector<std::array<u32, 3>> triangles;    // counter-clockwise seen from the front, indices into the vertex arrays
  std::vector<u32> materials;                   // empty (every triangle uses material 0), or one per triangle:
                                                // an index into MeshFile::materials
};

// A mesh of the file placed in the file's space: glTF nodes place meshes (a mesh may be placed several times);
// OBJ and PLY place their meshes once each, unmoved.
struct MeshPlacement {
  u32 mesh;
  AffineTransform transform;
};

// Everything read from one model file.
struct MeshFile {
  std::filesystem::path path;
  std::vector<TriangleMesh> meshes;
  std::vector<MeshMaterial> materials;  // at least one: readers add a default (MeshMaterial{}) where the file has none
  std::vector<TextureImage> textures;   // decoded 8-bit sRGB images (read_texture_image's limits apply)
  std::vector<MeshPlacement> placements;
  std::optional<CameraSettings> camera;  // glTF: the first camera of the scene, placed by its node
  std::vector<std::string> warnings;     // each feature of the file that is not rendered, named once
};

}  // namespace pt
