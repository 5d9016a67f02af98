// Reading model files (Wavefront OBJ, PLY, glTF 2.0) into the parsed scene's meshes (scene/mesh.hpp), with one
// located error for any bad input.
#pragma once

#include <filesystem>

#include "scene/mesh.hpp"

namespace pt {

// Limits on one model file, beyond those of textures: larger counts are refused as absurd rather than attempted.
inline constexpr u64 kMaxMeshTriangles = u64{1} << 28;  // all meshes of a file together
inline constexpr u64 kMaxMeshVertices = u64{1} << 28;

// Whether a file that a model file names (an MTL library, a texture, a glTF buffer or image) may be read although it
// lies outside the model's folder. A model from elsewhere must not read the user's other files (`mtllib
// ../../.ssh/id_rsa`): by default it may name only files in its own folder and below, links resolved.
enum class ModelReferences { kInsideItsFolder, kAnywhere };
inline ModelReferences model_references(bool anywhere) { return anywhere ? ModelReferences::kAnywhere : ModelReferences::kInsideItsFolder; }

// Reads a model file by its extension (.obj, .ply, .gltf, .glb). Throws InputError naming the file and, where
// the format has them, the line or the JSON path of the problem: missing or unreadable files and buffers, indices
// out of range, non-finite positions, unsupported primitive modes, recursive node hierarchies, and so on.
MeshFile read_mesh_file(const std::filesystem::path& path, ModelReferences references = ModelReferences::kInsideItsFolder);

// With its MTL material libraries and their textures.
MeshFile read_obj_file(const std::filesystem::path& path, ModelReferences references = ModelReferences::kInsideItsFolder);
// ASCII and binary (either byte order); a PLY file names no other file.
MeshFile read_ply_file(const std::filesystem::path& path);
// .gltf (external or embedded buffers and images) and .glb.
MeshFile read_gltf_file(const std::filesystem::path& path, ModelReferences references = ModelReferences::kInsideItsFolder);

}  // namespace pt
