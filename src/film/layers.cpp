// Render layers beside the image (layers.hpp).
#include "film/layers.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "base/errors.hpp"
#include "base/number_formats.hpp"

namespace pt {

std::vector<std::string> layer_names() { return {"albedo", "normal", "depth", "samples"}; }

std::vector<std::string> parse_layer_list(const std::string& text, const std::string& given_as) {
  const std::vector<std::string> known = layer_names();
  if (text == "all") return known;
  std::vector<bool> wanted(known.size(), false);
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string name = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const auto found = std::find(known.begin(), known.end(), name);
    if (found == known.end()) throw InputError(fmt::format("{}: no layer '{}' (layers: {}, or all)", given_as, clip(name), fmt::join(known, ", ")));
    wanted[static_cast<std::size_t>(found - known.begin())] = true;
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  std::vector<std::string> names;
  for (std::size_t i = 0; i < known.size(); ++i)
    if (wanted[i]) names.push_back(known[i]);
  return names;
}

std::vector<ImageChannel> RenderLayers::image_channels() const {
  std::vector<ImageChannel> out;
  for (const auto& [name, values] : channels) out.push_back({name, values.data()});
  return out;
}

const std::vector<float>& RenderLayers::channel(const std::string& name) const {
  for (const auto& [n, values] : channels)
    if (n == name) return values;
  throw BackendError(fmt::format("no layer channel '{}'", name));
}

template <class T>
RenderLayers render_layers(RenderBackend<T>& backend, const FlatScene<T>& scene, const RenderedFilm& film, const std::vector<std::string>& names) {
  RenderLayers layers;
  layers.width = film.width;
  layers.height = film.height;
  const std::size_t pixels = static_cast<std::size_t>(film.width) * film.height;
  const auto wants = [&](const char* name) { return std::find(names.begin(), names.end(), name) != names.end(); };
  const auto plane = [&](const std::string& name) -> std::vector<float>& {
    layers.channels.emplace_back(name, std::vector<float>(pixels));
    return layers.channels.back().second;
  };
  if (wants("albedo") || wants("normal") || wants("depth")) {
    std::vector<LayerPixel> sums(pixels, LayerPixel{});
    backend.render_layers(0, std::min(film.samples_done, kLayerSamples), sums);
    const double to_scene_units = 1.0 / scene.scale;  // the flat scene's lengths are the scene's times scene.scale
    if (wants("albedo"))
      for (int c = 0; c < 3; ++c) {
        std::vector<float>& out = plane(std::string("albedo.") + "RGB"[c]);
        for (std::size_t i = 0; i < pixels; ++i) out[i] = sums[i].samples ? static_cast<float>(sums[i].albedo[c] / sums[i].samples) : 0.0f;
      }
    if (wants("normal"))
      for (int c = 0; c < 3; ++c) {
        std::vector<float>& out = plane(std::string("normal.") + "XYZ"[c]);
        for (std::size_t i = 0; i < pixels; ++i) out[i] = sums[i].samples ? static_cast<float>(sums[i].normal[c] / sums[i].samples) : 0.0f;
      }
    if (wants("depth")) {
      std::vector<float>& out = plane("depth.Z");
      for (std::size_t i = 0; i < pixels; ++i)
        out[i] = sums[i].hits ? static_cast<float>(sums[i].depth / sums[i].hits * to_scene_units) : std::numeric_limits<float>::infinity();
    }
  }
  if (wants("samples")) {
    std::vector<float>& out = plane("samples.Y");
    const std::span<const FilmPixel> film_pixels = film.pixels();
    for (std::size_t i = 0; i < pixels; ++i) out[i] = static_cast<float>(film_pixels[i].samples);
  }
  return layers;
}

#define PT_INSTANTIATE_LAYERS(...)                                                                                                  \
  template RenderLayers render_layers<__VA_ARGS__>(RenderBackend<__VA_ARGS__>&, const FlatScene<__VA_ARGS__>&, const RenderedFilm&, \
                                                   const std::vector<std::string>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_LAYERS)

}  // namespace pt
