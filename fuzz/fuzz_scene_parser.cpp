// Fuzz target: any byte string given to the scene parser either parses (and then flattens) or raises one
// InputError; it never crashes, hangs, leaks or trips a sanitizer.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    pt::SceneDescription scene = pt::parse_scene(text, "fuzz.json", "fuzz-images-do-not-exist");
    // Keep flattening cheap: the BVH build is what a parsed scene goes through next.
    if (scene.objects.size() <= 4096) {
      pt::RenderSettings settings = scene.render;
      (void)pt::flatten_scene<float>(scene, settings);
    }
  } catch (const pt::InputError&) {
  }
  return 0;
}
