// The integrators written once over the device interface: their GPU paths (one sample per megakernel launch,
// batches between synchronisations, the large wavefront pool, bdpt's and vcm's stages) run here on a device that
// computes on the CPU but says it is not the host, and must give the CPU backend's film bit for bit, with the launches
// the GPU path makes. Like a GPU it hands out memory that is not cleared, and it refuses a host wait inside a timed
// span (a GPU's timers are read there).
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "backends/cpu/cpu_device.hpp"
#include "backends/device_backend.hpp"
#include "loading/scene_loader.hpp"
#include "test_support.hpp"

namespace pt {
namespace {

// The CPU device, reporting itself as a GPU (not the host) and counting what the integrators ask of it.
class CountingGpuLikeDevice {
 public:
  struct Counts {
    u32 item_launches = 0, image_launches = 0, synchronisations = 0, timers = 0;
  };

  explicit CountingGpuLikeDevice(Counts* counts) : cpu_(2), counts_(counts) {}

  std::string kind() const { return "gpu-like"; }
  std::string description() const { return "the CPU device, not the host"; }
  bool host() const { return false; }
  Integrator preferred_integrator() const { return Integrator::kWavefront; }
  bool memory_on_host() const { return false; }
  bool times_on_device() const { return true; }
  void* allocate(std::size_t bytes, const char* what) {
    void* memory = cpu_.allocate(bytes, what);
    std::memset(memory, 0xA5, bytes);  // what a GPU's fresh memory may hold: not zeros
    return memory;
  }
  void release(void* pointer) { cpu_.release(pointer); }
  void copy_to_device(void* to, const void* from, std::size_t bytes, const char* what) { cpu_.copy_to_device(to, from, bytes, what); }
  void copy_to_host(void* to, const void* from, std::size_t bytes, const char* what) {
    refuse_a_wait_inside_a_timer(what);
    cpu_.copy_to_host(to, from, bytes, what);
  }
  void clear(void* to, std::size_t bytes, const char* what) { cpu_.clear(to, bytes, what); }
  void synchronise(const char* what) {
    refuse_a_wait_inside_a_timer(what);
    ++counts_->synchronisations;
    cpu_.synchronise(what);
  }
  template <class Kernel>
  void launch(const char* what, u32 count, const Kernel& kernel) {
    ++counts_->item_launches;
    cpu_.launch(what, count, kernel);
  }
  template <class Kernel>
  void launch_image(const char* what, u32 width, u32 height, const Kernel& kernel) {
    ++counts_->image_launches;
    cpu_.launch_image(what, width, height, kernel);
  }
  using Timer = CpuDevice::Timer;
  Timer start_timer() {
    ++counts_->timers;
    ++open_timers_;
    return cpu_.start_timer();
  }
  void stop_timer(Timer timer, double* seconds) {
    --open_timers_;
    cpu_.stop_timer(timer, seconds);
  }
  u64 saturations() const { return cpu_.saturations(); }

 private:
  void refuse_a_wait_inside_a_timer(const char* what) const {
    if (open_timers_ != 0) throw std::logic_error(std::string("the host waited inside a timed span: ") + what);
  }

  int open_timers_ = 0;
  CpuDevice cpu_;
  Counts* counts_;
};
static_assert(Device<CountingGpuLikeDevice>);

std::vector<FilmPixel> render_gpu_like(const FlatScene<float>& scene, Integrator integrator, const std::vector<u32>& passes,
                                       CountingGpuLikeDevice::Counts& counts, std::string* name = nullptr) {
  DeviceBackend<CountingGpuLikeDevice, float> backend(integrator, &counts);
  if (name) *name = backend.name();
  backend.upload(scene);
  u32 first = 0;
  for (u32 count : passes) {
    backend.render(first, count);
    first += count;
  }
  EXPECT_TRUE(backend.device_seconds().has_value());
  std::vector<FilmPixel> film;
  backend.read_film(film);
  return film;
}

TEST(DeviceLayer, GpuMegakernelPathLaunchesOneSampleAtATimeAndMatchesTheCpuBackend) {
  const FlatScene<float> scene = test::tiny_reference_scene<float>(1, 7);
  CountingGpuLikeDevice::Counts counts;
  std::string name;
  const std::vector<FilmPixel> film = render_gpu_like(scene, Integrator::kAuto, {1, 2, 3}, counts, &name);
  EXPECT_NE(name.find("wavefront"), std::string::npos) << "auto takes the device's preferred integrator: " << name;
  CountingGpuLikeDevice::Counts mega_counts;
  const std::vector<FilmPixel> mega = render_gpu_like(scene, Integrator::kMegakernel, {1, 2, 3}, mega_counts);
  EXPECT_EQ(mega_counts.image_launches, 6u);  // one launch per sample
  EXPECT_EQ(mega_counts.item_launches, 0u);
  EXPECT_GE(mega_counts.synchronisations, 3u);  // at least one batch per render call, each ending in a wait
  EXPECT_TRUE(test::same_film(mega, test::render_film(scene, 2, {6})));
  EXPECT_TRUE(test::same_film(film, mega)) << "the wavefront's GPU path against the megakernel's";
}

TEST(DeviceLayer, GpuWavefrontPathRunsStagesAndMatchesTheCpuBackend) {
  const FlatScene<float> scene = test::tiny_reference_scene<float>(1, 7);
  CountingGpuLikeDevice::Counts counts;
  const std::vector<FilmPixel> film = render_gpu_like(scene, Integrator::kWavefront, {2, 2}, counts);
  EXPECT_EQ(counts.image_launches, 0u);
  EXPECT_GT(counts.item_launches, 4u);             // generate, intersect, escaped, shade..., accumulate
  EXPECT_EQ(counts.timers, counts.item_launches);  // every stage timed
  EXPECT_TRUE(test::same_film(film, test::render_film(scene, 2, {4}, Integrator::kWavefront)));
  EXPECT_TRUE(test::same_film(film, test::render_film(scene, 2, {4}, Integrator::kMegakernel)));
}

// bdpt's and vcm's GPU paths: with a light that starts subpaths the stages (light subpaths, the merging grid, camera
// subpaths, connections, gathering) over bands of rows, light vertices slot by slot; the CPU backend's film bit for bit
// (one kernel a sample for bdpt, one launch for vcm's camera side). The Cornell box with its boxes and the glass sphere.
TEST(DeviceLayer, GpuBidirectionalPathsMatchTheCpuBackend) {
  for (const char* name : {"cornell-box", "caustics"}) {
    const SceneDescription description = load_scene_file(test::scene_path(std::string(name) + ".json"));
    RenderSettings settings = description.render;
    settings.width = 40;
    settings.height = 24;
    settings.max_depth = 6;
    const FlatScene<float> scene = flatten_scene<float>(description, settings);
    for (Integrator integrator : {Integrator::kBidirectional, Integrator::kVertexMerging}) {
      CountingGpuLikeDevice::Counts counts;
      const std::vector<FilmPixel> film = render_gpu_like(scene, integrator, {1, 2}, counts);
      EXPECT_GE(counts.item_launches, 3u * 3) << name << ": connections, gathering and splats at every sample";
      EXPECT_TRUE(test::same_film(film, test::render_film(scene, 2, {3}, integrator))) << name << ", " << integrator_name(integrator);
    }
  }
}

// The bytes a path costs in flight, derived from the field lists, are what the allocation takes per pool slot:
// every array but the counters and the per-item results is sized by the pool (the material queues, one after
// another, by a multiple of it).
TEST(DeviceLayer, BytesPerPathMatchTheWavefrontAllocation) {
  constexpr u32 kCapacity = 1000, kItems = 77;
  WavefrontView<float> view{};
  std::size_t per_slot_bytes = 0, other_bytes = 0;
  view.for_each_array(kCapacity, kItems, [&](auto*& array, std::size_t entries) {
    const std::size_t bytes = entries * sizeof(*array);
    (entries % kCapacity == 0 ? per_slot_bytes : other_bytes) += bytes;
  });
  EXPECT_EQ(per_slot_bytes, std::size_t{kCapacity} * WavefrontView<float>::kBytesPerPath);
  EXPECT_EQ(other_bytes, kWavefrontCounters * sizeof(u32) + kItems * sizeof(SampleResult<float>));
}

}  // namespace
}  // namespace pt
