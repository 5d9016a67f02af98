// Where a value of a parsed scene was written in its file, found again for an error message.
#include <fstream>
#include <iterator>
#include <memory>

#include <fmt/format.h>

#include "scene/json_positions.hpp"
#include "scene/scene.hpp"

namespace pt {

std::string source_position(const SceneDescription& scene, const std::string& pointer) {
  std::shared_ptr<const std::string> text = scene.written.text;
  if (!text && !scene.written.file.empty()) {
    std::ifstream in(scene.written.file, std::ios::binary);
    std::string read((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.good() || in.eof()) text = std::make_shared<const std::string>(std::move(read));
  }
  if (!text) return scene.source;
  const TextPosition at = JsonPositions(*text).find(pointer);
  return at.line ? fmt::format("{}:{}:{}", scene.source, at.line, at.column) : scene.source;
}

}  // namespace pt
