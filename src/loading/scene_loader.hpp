// Reading a JSON scene file into a SceneDescription, with one clear error for any bad input.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "loading/model_files.hpp"
#include "scene/scene.hpp"

namespace pt {

// Reads and checks a scene file; image paths are relative to the file's folder. A model file (.obj, .ply, .gltf,
// .glb) is a scene of its own (scene_from_model_file). `references` says which files model files may name. Throws
// InputError.
SceneDescription load_scene_file(const std::filesystem::path& file, ModelReferences references = ModelReferences::kInsideItsFolder);

// A scene of one model file: its meshes and materials, its camera where it has one (glTF) or else one that frames
// it from the front, and the default sky. Throws InputError.
SceneDescription scene_from_model_file(const std::filesystem::path& file, ModelReferences references = ModelReferences::kInsideItsFolder);

// Parses scene text; `source` names it in messages and `base_folder` resolves image paths. Throws InputError.
SceneDescription parse_scene(std::string_view text, const std::string& source, const std::filesystem::path& base_folder,
                             ModelReferences references = ModelReferences::kInsideItsFolder);

// Adds a model file to the scene: its materials and textures (as the scene's own, MeshMaterial mapped onto them)
// and the file to SceneDescription::mesh_files, whose index it returns; its warnings to the scene's. `pointer`
// names the file's place in messages about its values. Throws InputError when the scene's images grow too large.
u32 add_mesh_file(SceneDescription& scene, std::shared_ptr<const MeshFile> file, const std::string& pointer);

// Limits that keep a scene renderable: larger values are rejected as absurd rather than attempted.
inline constexpr u32 kMaxImageSide = 16384;
inline constexpr u64 kMaxImagePixels = 64ull * 1024 * 1024;
inline constexpr u32 kMaxSamplesPerPixel = 1u << 20;
inline constexpr u32 kMaxDepth = 10000;
// All image textures of a scene together, as stored (three bytes per texel); also keeps texel offsets within 32 bits.
inline constexpr u64 kMaxSceneTexelBytes = u64{1} << 30;

}  // namespace pt
