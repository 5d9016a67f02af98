// Reading model files (Wavefront OBJ, PLY, glTF 2.0) into the parsed scene's meshes (scene/mesh.hpp), with one
// located error for any bad input.
#pragma once

#include <filesystem>

#include "scene/mesh.hpp"

namespace pt {

// Limits on one model file, beyond those of textures: larger counts are refused as absurd rather than attempted.
inline constexpr u64 kMaxMeshTriangles = u64{1} << 28;  // all meshes of a file together
inline constexpr u64 kMaxMeshVertices = u64{1} << 28;

// Reads a model file by its extension (.obj, .ply, .gltf, .glb). Throws InputError naming the file and, where
// the format has them, the line or the JSON path of the problem: missing or unreadable files and buffers, indices
// out of range, non-finite positions, unsupported primitive modes, recursive node hierarchies, and so on.
MeshFile read_mesh_file(const std::filesystem::path& path);

MeshFile read_obj_file(const std::filesystem::path& path);   // with its MTL material libraries
MeshFile read_ply_file(const std::filesystem::path& path);   // ASCII and binary (either byte order)
MeshFile read_gltf_file(const std::filesystem::path& path);  // .gltf (external or embedded buffers) and .glb

}  // namespace pt
