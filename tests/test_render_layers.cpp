// Render layers (film/layers.hpp): the albedo, normal and distance of what each camera sample meets first, and each
// pixel's sample count, are what the scene says they are; they depend on no thread count, integrator, split of the
// samples or device; and they are written as channels of the OpenEXR image.
#include <gtest/gtest.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "backends/registry.hpp"
#include "film/layers.hpp"
#include "kernel/fixed_point.hpp"
#include "test_support.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif

namespace pt::render_layers_test {
namespace {

// A quad of albedo (0.25, 0.5, 0.75) filling the middle of the view, 4 units in front of the camera, facing it, under
// a sky of constant radiance (0.2, 1.5, 0.4): the sky's albedo is that clamped, (0.2, 1, 0.4).
const char* kWall = R"({
  "render": {"width": 24, "height": 16, "samples_per_pixel": 8, "max_depth": 4},
  "camera": {"look_from": [0, 0, 4], "look_at": [0, 0, 0], "vertical_fov": 40},
  "background": {"type": "sky", "horizon": [0.2, 1.5, 0.4], "zenith": [0.2, 1.5, 0.4]},
  "objects": [{"type": "quad", "corner": [-1, -0.5, 0], "u": [2, 0, 0], "v": [0, 1, 0],
               "material": {"type": "lambertian", "albedo": [0.25, 0.5, 0.75]}}]
})";

template <class T>
struct Rendered {
  FlatScene<T> flat;
  std::unique_ptr<RenderBackend<T>> backend;
  RenderedFilm film;
  RenderLayers layers;
};

template <class T>
Rendered<T> render_with_layers(const SceneDescription& scene, const std::string& backend = "cpu", unsigned threads = 0,
                               Integrator integrator = Integrator::kMegakernel, double scale = 0) {
  Rendered<T> r{flatten_scene<T>(scene, scene.render, scale), make_backend<T>(backend, threads, 0, integrator), {}, {}};
  r.film = render_film(*r.backend, r.flat);
  r.layers = render_layers(*r.backend, r.flat, r.film, layer_names());
  return r;
}

TEST(RenderLayers, OfAWallFacingTheCameraAreItsAlbedoNormalAndDistance) {
  const SceneDescription scene = test::parse(kWall);
  const Rendered<double> r = render_with_layers<double>(scene);
  const RenderLayers& layers = r.layers;
  ASSERT_EQ(layers.channels.size(), 8u);
  const char* names[] = {"albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "depth.Z", "samples.Y"};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(layers.channels[i].first, names[i]);
  const double tan_half = std::tan(20 * test::kPi / 180), aspect = 24.0 / 16.0;
  int wall = 0, sky = 0;
  for (u32 y = 0; y < 16; ++y)
    for (u32 x = 0; x < 24; ++x) {
      const std::size_t i = y * 24 + x;
      // The pixel's centre in the image plane at distance 1, and where its ray meets the wall's plane (z = 0).
      const double px = (2 * (x + 0.5) / 24 - 1) * tan_half * aspect, py = (1 - 2 * (y + 0.5) / 16) * tan_half;
      const double hit_x = 4 * px, hit_y = 4 * py;
      // Pixels whose whole footprint is on the wall, or off it (footprint: half a pixel, 4 units away, each way).
      const double half_pixel = 4 * tan_half / 16;
      const bool inside = std::abs(hit_x) < 1 - half_pixel && std::abs(hit_y) < 0.5 - half_pixel;
      const bool outside = std::abs(hit_x) > 1 + half_pixel || std::abs(hit_y) > 0.5 + half_pixel;
      EXPECT_EQ(layers.channel("samples.Y")[i], 8.0f);
      if (inside) {
        ++wall;
        EXPECT_FLOAT_EQ(layers.channel("albedo.R")[i], 0.25f);
        EXPECT_FLOAT_EQ(layers.channel("albedo.G")[i], 0.5f);
        EXPECT_FLOAT_EQ(layers.channel("albedo.B")[i], 0.75f);
        EXPECT_FLOAT_EQ(layers.channel("normal.X")[i], 0.0f);
        EXPECT_FLOAT_EQ(layers.channel("normal.Y")[i], 0.0f);
        EXPECT_FLOAT_EQ(layers.channel("normal.Z")[i], 1.0f);
        // The mean distance over the pixel's samples: the centre's, within the change across a pixel.
        const double centre = 4 * std::sqrt(1 + px * px + py * py);
        EXPECT_NEAR(layers.channel("depth.Z")[i], centre,
                    4 * (std::sqrt(1 + (std::abs(px) + 2 * tan_half / 16) * (std::abs(px) + 2 * tan_half / 16) +
                                   (std::abs(py) + 2 * tan_half / 16) * (std::abs(py) + 2 * tan_half / 16)) -
                         std::sqrt(1 + px * px + py * py)) +
                        1e-6);
      } else if (outside) {
        ++sky;
        EXPECT_FLOAT_EQ(layers.channel("albedo.R")[i], 0.2f);
        EXPECT_FLOAT_EQ(layers.channel("albedo.G")[i], 1.0f);
        EXPECT_FLOAT_EQ(layers.channel("albedo.B")[i], 0.4f);
        for (const char* n : {"normal.X", "normal.Y", "normal.Z"}) EXPECT_EQ(layers.channel(n)[i], 0.0f);
        EXPECT_EQ(layers.channel("depth.Z")[i], std::numeric_limits<float>::infinity());
      }
    }
  EXPECT_GE(wall, 30);
  EXPECT_GE(sky, 30);
}

// The layer samples are the image's first ones (at most kLayerSamples), whatever split of the image's own samples.
TEST(RenderLayers, DependOnNoThreadCountIntegratorOrSplitOfTheSamples) {
  const SceneDescription scene = test::parse(test::read_text_file(test::scene_path("cornell-box.json")));
  SceneDescription small = scene;
  small.render.width = 40;
  small.render.height = 30;
  small.render.samples_per_pixel = 20;
  const Rendered<float> one = render_with_layers<float>(small, "cpu", 1, Integrator::kMegakernel);
  const Rendered<float> two = render_with_layers<float>(small, "cpu", 2, Integrator::kWavefront);
  const Rendered<float> bidirectional = render_with_layers<float>(small, "cpu", 2, Integrator::kBidirectional);
  for (const Rendered<float>* other : {&two, &bidirectional}) {
    ASSERT_EQ(one.layers.channels.size(), other->layers.channels.size());
    for (std::size_t c = 0; c < one.layers.channels.size(); ++c)
      EXPECT_EQ(0, std::memcmp(one.layers.channels[c].second.data(), other->layers.channels[c].second.data(), one.layers.channels[c].second.size() * 4))
          << one.layers.channels[c].first;
  }
  // Samples [0, 16) in one call, or as 5 and 11.
  const FlatScene<float> flat = flatten_scene<float>(small, small.render);
  const auto backend = make_backend<float>("cpu", 2, 0);
  backend->upload(flat);
  std::vector<LayerPixel> whole(40 * 30, LayerPixel{}), split(40 * 30, LayerPixel{});
  backend->render_layers(0, 16, whole);
  backend->render_layers(0, 5, split);
  backend->render_layers(5, 11, split);
  EXPECT_EQ(0, std::memcmp(whole.data(), split.data(), whole.size() * sizeof(LayerPixel)));
  EXPECT_EQ(whole[0].samples, kLayerSamples);
  // A render stopped early: the samples layer counts what each pixel holds.
  const std::vector<FilmPixel> partial = test::render_film(flat, 2, {3});
  RenderedFilm stopped;
  stopped.copy = partial;
  stopped.width = 40;
  stopped.height = 30;
  stopped.samples_done = 3;
  const RenderLayers counted = render_layers(*backend, flat, stopped, {"samples"});
  ASSERT_EQ(counted.channels.size(), 1u);
  for (float s : counted.channel("samples.Y")) EXPECT_EQ(s, 3.0f);
}

// A scene scaled to fit a fixed-point format (docs/numerics.md) gives its depth in the scene's own units: the same
// scene scaled by 1/4 has the same depths; and a fixed-point format gives the same as double, within its steps.
TEST(RenderLayers, DepthIsInTheScenesUnitsWhateverTheScaleAndFormat) {
  SceneDescription scene = test::parse(test::read_text_file(test::scene_path("cornell-box.json")));
  scene.render.width = 24;
  scene.render.height = 24;
  scene.render.samples_per_pixel = 4;
  const Rendered<double> d = render_with_layers<double>(scene);
  const Rendered<double> quarter = render_with_layers<double>(scene, "cpu", 0, Integrator::kMegakernel, 0.25);
  ASSERT_EQ(quarter.flat.scale, 0.25);
  const Rendered<Fixed<16, 16>> q = render_with_layers<Fixed<16, 16>>(scene);
  const std::vector<float>&a = d.layers.channel("depth.Z"), &b = quarter.layers.channel("depth.Z"), &c = q.layers.channel("depth.Z");
  std::size_t close = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::isinf(a[i])) {  // every sample left the scene (the box is open towards the camera)
      EXPECT_EQ(b[i], a[i]) << i;
      close += c[i] == a[i];
      continue;
    }
    EXPECT_NEAR(b[i], a[i], 1e-5 * a[i]) << i;
    close += std::abs(c[i] - a[i]) <= 1e-3 * a[i];
  }
  EXPECT_GE(close, a.size() * 95 / 100);
}

TEST(RenderLayers, AreChannelsOfTheOpenExrImage) {
  const Rendered<float> r = render_with_layers<float>(test::parse(kWall));
  test::TempDir dir;
  ImageRows rows = film_rows(r.film);
  rows.channels = r.layers.image_channels();
  write_image(dir / "layers.exr", rows);
  Imf::InputFile in((dir / "layers.exr").c_str());
  std::vector<std::string> names;
  for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) names.push_back(c.name());
  // OpenEXR lists channels by name.
  EXPECT_EQ(names, (std::vector<std::string>{"B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z", "normal.X", "normal.Y", "normal.Z",
                                             "samples.Y"}));
  const int width = 24, height = 16;
  for (const auto& [name, values] : r.layers.channels) {
    std::vector<float> read(width * height);
    Imf::FrameBuffer frame;
    frame.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(read.data()), sizeof(float), sizeof(float) * width));
    in.setFrameBuffer(frame);
    in.readPixels(0, height - 1);
    EXPECT_EQ(0, std::memcmp(read.data(), values.data(), read.size() * sizeof(float))) << name;
  }
  // Other formats have no place for them.
  EXPECT_THROW(write_image(dir / "layers.png", rows), InputError);
  EXPECT_THROW(write_image(dir / "layers.pfm", rows), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir / "layers.png"));
}

TEST(RenderLayers, NamesAreCheckedAndKeptInOrder) {
  EXPECT_EQ(parse_layer_list("depth,albedo", "--layers"), (std::vector<std::string>{"albedo", "depth"}));
  EXPECT_EQ(parse_layer_list("all", "--layers"), layer_names());
  EXPECT_EQ(parse_layer_list("samples,samples", "--layers"), (std::vector<std::string>{"samples"}));
  for (const char* bad : {"", "albedo,", "nrm", "albedo,,depth", "ALBEDO"}) {
    try {
      parse_layer_list(bad, "--layers");
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--layers: no layer '", 0), 0u) << e.what();
    }
  }
}

// The program writes them with --layers, into OpenEXR only, refusing other formats before it renders.
TEST(RenderLayers, CommandLineWritesThemAndRefusesOtherFormats) {
  test::TempDir dir;
  const std::string program = test::pathtracer_binary(), scene = test::scene_path("tiny.json").string();
  const std::string common = " --width 16 --height 12 --spp 2 -q";
  ASSERT_EQ(std::system((program + " render " + scene + common + " --layers normal,samples -o " + (dir / "l.exr").string()).c_str()), 0);
  Imf::InputFile in((dir / "l.exr").c_str());
  EXPECT_NE(in.header().channels().findChannel("normal.Z"), nullptr);
  EXPECT_NE(in.header().channels().findChannel("samples.Y"), nullptr);
  EXPECT_EQ(in.header().channels().findChannel("albedo.R"), nullptr);
  const std::string refused =
      program + " render " + scene + common + " --layers albedo -o " + (dir / "l.png").string() + " 2>" + (dir / "err.txt").string();
  EXPECT_NE(std::system(refused.c_str()), 0);
  EXPECT_NE(test::read_text_file(dir / "err.txt").find("only OpenEXR holds render layers"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "l.png"));
}

// On a GPU the same layers as on the CPU, within the rounding of the GPU's own arithmetic (fused multiply-adds, its
// square roots): a sample may meet another surface only at an edge.
TEST(RenderLayers, GpuLayersMatchTheCpus) {
#if !PT_HAVE_CUDA
  GTEST_SKIP() << "the CUDA backend is not built (no nvcc)";
#else
  if (cuda_device_count() == 0) GTEST_SKIP() << "no usable GPU on this machine";
  for (const char* name : {"cornell-box.json", "meshes.json", "normal-maps.json", "environment.json"}) {
    SceneDescription scene = load_scene_file(test::scene_path(name));
    scene.render.width = 64;
    scene.render.height = 48;
    scene.render.samples_per_pixel = 16;
    const Rendered<float> cpu = render_with_layers<float>(scene, "cpu");
    const Rendered<float> gpu = render_with_layers<float>(scene, "cuda");
    for (std::size_t c = 0; c < cpu.layers.channels.size(); ++c) {
      const std::vector<float>&a = cpu.layers.channels[c].second, &b = gpu.layers.channels[c].second;
      std::size_t close = 0;
      for (std::size_t i = 0; i < a.size(); ++i) close += a[i] == b[i] || std::abs(a[i] - b[i]) <= 1e-4f * std::max(1.0f, std::abs(a[i]));
      EXPECT_GE(close, a.size() * 98 / 100) << name << " " << cpu.layers.channels[c].first;
    }
  }
#endif
}

}  // namespace
}  // namespace pt::render_layers_test
