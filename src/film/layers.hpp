// Render layers beside the image: first-hit albedo, shading normal and depth (the guides denoisers take) and each
// pixel's sample count, rendered after the image's passes and resolved into planes of floats.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "backends/backend.hpp"
#include "film/film.hpp"
#include "image/image_io.hpp"

namespace pt {

// The layers there are, in the order they are written.
std::vector<std::string> layer_names();

// Reads a comma-separated list of layer names ("albedo,normal"; "all" for every one), each once, in the order of
// layer_names(). Throws InputError starting with `given_as` (how the list was given: "--layers nrm") and naming
// the name it does not know.
std::vector<std::string> parse_layer_list(const std::string& text, const std::string& given_as);

// The layer samples of a pixel: the image's first samples, at most kLayerSamples (16 leave the guides of an
// antialiased edge smooth; first hits cost a camera ray each, so the pass is a small part of any render with more).
inline constexpr u32 kLayerSamples = 16;

// A render's layers, one plane of floats a channel, row-major, rows from the top:
//  - albedo.R, albedo.G, albedo.B: the mean over the layer samples of the albedo of what each meets first (the
//    background's radiance clamped to [0, 1] where it meets nothing);
//  - normal.X, normal.Y, normal.Z: the mean of its shading normal, facing the camera, in world space (0 where it
//    meets nothing);
//  - depth.Z: the mean distance along the camera ray to it, in the scene's units, over the samples that hit
//    something (infinity where none did);
//  - samples.Y: the samples the image's pixel holds (those that were finite).
struct RenderLayers {
  u32 width = 0, height = 0;
  std::vector<std::pair<std::string, std::vector<float>>> channels;
  std::vector<ImageChannel> image_channels() const;  // for the image writer, referring to these planes
  const std::vector<float>& channel(const std::string& name) const;
};

// Renders and resolves the layers `names` (from parse_layer_list) of a finished render `film` of `scene` on
// `backend`: layer samples [0, min(film.samples_done, kLayerSamples)). The image's film is left as it was.
template <class T>
RenderLayers render_layers(RenderBackend<T>& backend, const FlatScene<T>& scene, const RenderedFilm& film, const std::vector<std::string>& names);

}  // namespace pt
