// A render backend made of a device and the integrators written once over it: the scene and film in device
// memory, the megakernel or the wavefront integrator, timing and naming. A backend's source file instantiates
// this with its device class (compiled by the backend's compiler, since the launches are templates).
#pragma once

#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "backends/backend.hpp"
#if defined(PT_CUDA_COMPRESSED_BVH)
#include "flat/compressed_bvh_builder.hpp"
#endif
#include "integrators/bidirectional.hpp"
#include "integrators/device.hpp"
#include "integrators/megakernel.hpp"
#include "integrators/wavefront.hpp"

namespace pt {

template <Device D, class T>
class DeviceBackend final : public RenderBackend<T> {
 public:
  template <class... DeviceArguments>
  explicit DeviceBackend(Integrator integrator, DeviceArguments&&... arguments)
      : device_(std::forward<DeviceArguments>(arguments)...),
        integrator_(integrator != Integrator::kAuto ? integrator : device_.preferred_integrator()) {}

  std::string name() const override {
    return device_.kind() + " (" + device_.description() + ", " + integrator_name(integrator_) + ")";
  }

  void upload(const FlatScene<T>& scene) override {
    wavefront_.reset();
    megakernel_.reset();
    bidirectional_.reset();
    memory_.release_all();
    // Where the device's memory is the host's (the CPU), the kernels read the scene's arrays where they are: a copy
    // would hold the scene twice (for a large mesh, about 90 bytes a triangle more at the peak).
    if (device_.memory_on_host())
      view_ = scene.view();
    else
      view_ = place_scene(scene, [&](const auto& array, const char* what) { return memory_.upload(array, what); });
#if defined(PT_CUDA_COMPRESSED_BVH)
    // This CUDA build walks the compressed wide tree in float (kernel/bvh.hpp, walk_tree): made from the wide one here,
    // held until the copies below are finished.
    std::vector<CompressedWideNode> compressed, mesh_compressed;
    if constexpr (std::is_same_v<T, float>) {
      compressed = compress_wide_bvh(scene.wide_nodes);
      mesh_compressed = compress_wide_bvh(scene.mesh_wide_nodes);
      view_.compressed_nodes = memory_.upload(compressed, "copying the compressed BVH");
      view_.meshes.compressed_nodes = memory_.upload(mesh_compressed, "copying the compressed mesh BVHs");
    }
#endif
    // A device that holds a copy of the scene elsewhere (the rtl backend's engine memory) takes it here.
    if constexpr (requires { device_.take_scene(scene); }) device_.take_scene(scene);
    const std::size_t pixels = static_cast<std::size_t>(scene.params.width) * scene.params.height;
    film_ = static_cast<FilmPixel*>(memory_.allocate(pixels * sizeof(FilmPixel), "allocating the film"));
    film_pixels_ = pixels;
    judgement_ = nullptr;  // released with the previous upload's memory
    device_.clear(film_, pixels * sizeof(FilmPixel), "clearing the film");
    if (integrator_ == Integrator::kWavefront) {
      wavefront_ = std::make_unique<WavefrontIntegrator<D, T>>(device_, view_, film_);
    } else if (integrator_ == Integrator::kBidirectional || integrator_ == Integrator::kVertexMerging) {
      const bool merging = integrator_ == Integrator::kVertexMerging;
      // A pixel stopped by adaptive sampling would still take other pixels' splats but no samples of its own.
      if (scene.noise_threshold > 0) throw BackendError(std::string("adaptive sampling (--noise-threshold) is not available with ") + integrator_name(integrator_));
      // Merging's densities are areas of discs times the number of light subpaths: fixed point has no room for them.
      if (merging && !std::is_floating_point_v<T>) throw BackendError("vcm renders in float and double only, not in fixed point");
      bidirectional_ = std::make_unique<BidirectionalIntegrator<D, T>>(
          device_, view_, film_, scene.bidirectional_schedule,
          std::any_of(scene.light_entries.begin(), scene.light_entries.end(), [](const LightEntry<T>& light) { return light.primitive != kNoLight; }),
          merging ? scene.merge_radius : 0.0);
    } else
      megakernel_ = std::make_unique<MegakernelIntegrator<D, T>>(device_, view_, film_);
    device_.synchronise("copying the scene");
    saturations_before_ = device_.saturations();
  }

  void render(u32 first_sample, u32 sample_count) override {
    if (bidirectional_)
      bidirectional_->render(first_sample, sample_count);
    else if (wavefront_)
      wavefront_->render(first_sample, sample_count);
    else
      megakernel_->render(first_sample, sample_count);
  }

  void render_rows(u32 first_row, u32 row_count, u32 first_sample, u32 sample_count, std::span<FilmPixel> band) override {
    const u32 width = view_.params.width;
    if (row_count == 0 || first_row + row_count > view_.params.height || band.size() != static_cast<std::size_t>(width) * row_count)
      throw BackendError("a band of rows outside the image");
    // Light tracing's splats land anywhere in the image, outside a band's rows.
    if (bidirectional_)
      throw BackendError(std::string(integrator_name(integrator_)) + " renders a whole image on one device: not in bands over several devices or processes");
    // Host memory: the kernels add to the caller's band where it is. Elsewhere the band goes through the device's
    // film, at its place in the image.
    if (device_.memory_on_host()) {
      integrate_rows(first_row, row_count, band.data(), first_sample, sample_count);
      device_.synchronise("finishing the band");
      return;
    }
    FilmPixel* on_device = film_ + static_cast<std::size_t>(first_row) * width;
    const std::size_t bytes = band.size() * sizeof(FilmPixel);
    device_.copy_to_device(on_device, band.data(), bytes, "copying a band of the film");
    integrate_rows(first_row, row_count, on_device, first_sample, sample_count);
    device_.copy_to_host(band.data(), on_device, bytes, "reading a band of the film back");
  }

  void render_layers(u32 first_sample, u32 sample_count, std::span<LayerPixel> layers) override {
    const u32 width = view_.params.width, height = view_.params.height;
    if (layers.size() != static_cast<std::size_t>(width) * height) throw BackendError("layers of another size than the image");
    // Host memory: the kernel adds to the caller's sums where they are; elsewhere they go to the device and back.
    const std::size_t bytes = layers.size() * sizeof(LayerPixel);
    DeviceAllocations<D> scratch(device_);
    LayerPixel* on_device = layers.data();
    if (!device_.memory_on_host()) {
      on_device = static_cast<LayerPixel*>(scratch.allocate(bytes, "allocating the layers"));
      device_.copy_to_device(on_device, layers.data(), bytes, "copying the layers");
    }
    for (u32 s = first_sample; s < first_sample + sample_count; ++s)
      device_.launch_image("rendering the layers", width, height, LayersSample<T>{view_, on_device, s});
    if (device_.memory_on_host())
      device_.synchronise("rendering the layers");
    else
      device_.copy_to_host(layers.data(), on_device, bytes, "reading the layers back");
  }

  void write_film(std::span<const FilmPixel> pixels) override {
    if (pixels.size() != film_pixels_) throw BackendError("a film of another size cannot be resumed");
    device_.copy_to_device(film_, pixels.data(), film_pixels_ * sizeof(FilmPixel), "restoring the film");
    device_.synchronise("restoring the film");
  }

  void read_film(std::vector<FilmPixel>& pixels) override {
    pixels.resize(film_pixels_);
    device_.copy_to_host(pixels.data(), film_, film_pixels_ * sizeof(FilmPixel), "reading the film back");
  }

  // On the device: two launches over the pixels and a counter read back, where a copy of the film to the host and
  // back took longer than the samples between two judgements on a GPU.
  std::size_t stop_clean_pixels(u32 width, u32 height, u32 samples_done, double threshold) override {
    if (bidirectional_) throw BackendError(std::string("adaptive sampling (--noise-threshold) is not available with ") + integrator_name(integrator_));
    if (static_cast<std::size_t>(width) * height != film_pixels_) throw BackendError("a film of another size cannot be judged");
    if (!judgement_) judgement_ = static_cast<u32*>(memory_.allocate((film_pixels_ + 1) * sizeof(u32), "allocating adaptive sampling's judgement"));
    u32* taking = judgement_ + film_pixels_;
    device_.clear(taking, sizeof(u32), "clearing adaptive sampling's count");
    const u32 pixels = static_cast<u32>(film_pixels_);
    device_.launch("launching adaptive sampling's judgement", pixels, AdaptiveJudge{film_, judgement_, taking, width, height, samples_done, threshold});
    device_.launch("launching adaptive sampling's judgement", pixels, AdaptiveApply{film_, judgement_});
    u32 count = 0;
    device_.copy_to_host(&count, taking, sizeof(u32), "reading adaptive sampling's count");
    return count;
  }

  std::span<const FilmPixel> film_on_host(std::vector<FilmPixel>& copy) override {
    if (!device_.memory_on_host()) return RenderBackend<T>::film_on_host(copy);
    device_.synchronise("finishing the film");
    return {film_, film_pixels_};
  }

  std::optional<double> device_seconds() const override {
    if (!device_.times_on_device()) return std::nullopt;
    return wavefront_ ? wavefront_->seconds() : megakernel_ ? megakernel_->seconds() : bidirectional_ ? bidirectional_->seconds() : 0.0;
  }

  std::vector<std::pair<std::string, double>> stage_seconds() const override {
    return wavefront_ ? wavefront_->stage_seconds() : bidirectional_ ? bidirectional_->stage_seconds() : std::vector<std::pair<std::string, double>>{};
  }

  u64 saturations() const override { return device_.saturations() - saturations_before_; }

  std::vector<std::string> report() const override {
    if constexpr (requires { device_.report(); }) return device_.report();
    return {};
  }

 private:
  void integrate_rows(u32 first_row, u32 row_count, FilmPixel* film, u32 first_sample, u32 sample_count) {
    if (wavefront_)
      wavefront_->render_rows(first_row, row_count, film, first_sample, sample_count);
    else
      megakernel_->render_rows(first_row, row_count, film, first_sample, sample_count);
  }

  D device_;  // first: destroyed last, after everything allocated on it
  Integrator integrator_;
  DeviceAllocations<D> memory_{device_};  // the scene's arrays and the film
  SceneView<T> view_{};
  FilmPixel* film_ = nullptr;
  std::size_t film_pixels_ = 0;
  u32* judgement_ = nullptr;  // adaptive sampling: a stop per pixel, then the count of pixels taking samples
  u64 saturations_before_ = 0;  // counted before the last upload
  std::unique_ptr<MegakernelIntegrator<D, T>> megakernel_;
  std::unique_ptr<BidirectionalIntegrator<D, T>> bidirectional_;
  std::unique_ptr<WavefrontIntegrator<D, T>> wavefront_;  // last: freed before the scene and film it points into
};

}  // namespace pt
