// Backend selection by name.
#include "backends/registry.hpp"

#include <algorithm>
#include <cstdlib>

#include <fmt/format.h>
#include <tbb/task_arena.h>

#include "backends/cpu/cpu_backend.hpp"
#include "backends/multi_backend.hpp"
#include "base/number_formats.hpp"
#if PT_HAVE_CUDA
#include "backends/cuda/cuda_backend.hpp"
#endif
#if PT_HAVE_SYCL
#include "backends/sycl/sycl_backend.hpp"
#endif
#if PT_HAVE_RTL
#include "backends/rtl/rtl_backend.hpp"
#endif

namespace pt {

std::vector<std::string> backend_names() {
  std::vector<std::string> names{"cpu", "auto"};
#if PT_HAVE_CUDA
  names.push_back("cuda");
#endif
#if PT_HAVE_SYCL
  names.push_back("sycl");
#endif
#if PT_HAVE_RTL
  names.push_back("rtl");
#endif
  return names;
}

std::string backend_choices() {
  std::string out;
  for (const std::string& n : backend_names()) out += (out.empty() ? "" : ", ") + n;
  return out;
}

template <class T>
std::unique_ptr<RenderBackend<T>> make_backend(const std::string& name, unsigned threads, int device, Integrator integrator, int sycl_device) {
#if PT_HAVE_RTL
  if (name == "rtl") return make_rtl_backend<T>(threads, integrator == Integrator::kAuto ? Integrator::kWavefront : integrator);
#endif
  if constexpr (is_fixed_v<T>) {
    // The GPU backends are built for float and double only: fixed-point formats are explored on the host.
    (void)device;
    (void)sycl_device;
    if (name != "cpu" && name != "auto")
      throw BackendError(fmt::format("number format {} renders on the cpu{} backend only", number_format_name<T>(), PT_HAVE_RTL ? " and rtl" : ""));
    return make_cpu_backend<T>(threads, integrator);
  } else {
#if PT_HAVE_SYCL
    if (name == "sycl") return make_sycl_backend<T>(sycl_device, integrator);
#else
    (void)sycl_device;
#endif
#if PT_HAVE_CUDA
    if (name == "cuda") return make_cuda_backend<T>(device, integrator);
    if (name == "auto") {
      if (cuda_device_count() > 0) {
        fmt::print(stderr, "backend auto: using cuda\n");
        return make_cuda_backend<T>(device, integrator);
      }
      fmt::print(stderr, "backend auto: no usable GPU, using cpu\n");
    }
#else
    (void)device;
    if (name == "auto") fmt::print(stderr, "backend auto: built without GPU backends, using cpu\n");
#endif
    return make_cpu_backend<T>(threads, integrator);
  }
}

namespace {

int gpu_count(const std::string& backend) {
#if PT_HAVE_CUDA
  if (backend == "cuda" || backend == "auto") return cuda_device_count();
#endif
  (void)backend;
  return 0;
}

// The process's rank among those on its node, as the MPI launchers (Open MPI, MPICH) and Slurm tell it.
int local_rank() {
  for (const char* name : {"OMPI_COMM_WORLD_LOCAL_RANK", "MPI_LOCALRANKID", "SLURM_LOCALID"})
    if (const char* value = std::getenv(name)) return std::max(0, std::atoi(value));
  return 0;
}

}  // namespace

DeviceList parse_device_list(const std::string& text, const std::string& backend) {
  // The rtl backend has one device, its engine's model: several would silently have been CPU devices.
  if (backend == "rtl" && text != "0")
    throw InputError(fmt::format("--device {}: the rtl backend has one device, its traversal engine (0)", text));
  const bool cpu_only = backend == "cpu" || (backend == "auto" && gpu_count(backend) == 0);
  DeviceList list;
  if (text == "all") {
    list.several = true;
    const int gpus = cpu_only ? 0 : gpu_count(backend);
    if (backend == "sycl") throw InputError("--device all: name the SYCL devices by index (see `pathtracer devices`)");
    if (gpus == 0) list.entries.push_back(kCpuDevice);
    for (int g = 0; g < gpus; ++g) list.entries.push_back(g);
    return list;
  }
  if (text == "local-rank") {
    const int gpus = gpu_count(backend);
    list.entries.push_back(cpu_only ? kCpuDevice : gpus > 0 ? local_rank() % gpus : local_rank());
    return list;
  }
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string entry = text.substr(start, comma - start);
    if (entry == "cpu") {
      list.entries.push_back(kCpuDevice);
    } else if (!entry.empty() && entry.size() <= 4 && entry.find_first_not_of("0123456789") == std::string::npos) {
      // Rendering on the CPU, index 0 (the default) names the CPU; any other would be silently the CPU too.
      if (cpu_only && std::atoi(entry.c_str()) != 0)
        throw InputError(fmt::format("--device {}: there is no device {} to render on: the backend is {}, whose one device is cpu (or 0)", text,
                                     entry, backend == "cpu" ? "cpu" : "auto, without a GPU,"));
      list.entries.push_back(cpu_only ? kCpuDevice : std::atoi(entry.c_str()));
    } else {
      throw InputError(fmt::format("--device {}: expected an index, all, cpu, local-rank, or indices and cpu joined by commas", text));
    }
    start = comma + 1;
  }
  list.several = list.entries.size() > 1;
  return list;
}

template <class T>
std::unique_ptr<RenderBackend<T>> make_render_backend(const std::string& backend, const DeviceList& devices, unsigned threads, Integrator integrator,
                                                      int sycl_device, std::vector<std::unique_ptr<BandWorker>> remote) {
  // For the sycl backend the indices of a list of several devices name SYCL devices; one device is --sycl-device's
  // where given, else --device's where it is not the default 0, else the runtime's choice (negative).
  const bool one_device = !devices.several && remote.empty();
  const auto sycl_index = [&](int entry) { return !one_device ? entry : sycl_device >= 0 ? sycl_device : entry != 0 ? entry : -1; };
  const auto make_one = [&](int entry, unsigned entry_threads) {
    if (entry == kCpuDevice) return make_backend<T>("cpu", entry_threads, 0, integrator);
    return make_backend<T>(backend, entry_threads, entry, integrator, backend == "sycl" ? sycl_index(entry) : sycl_device);
  };
  if (!devices.several && remote.empty()) return make_one(devices.entries.at(0), threads);
  // CPU devices share the threads asked for (all cores by default), less one for each GPU's driving thread.
  const auto cpus = static_cast<unsigned>(std::count(devices.entries.begin(), devices.entries.end(), kCpuDevice));
  const auto gpus = static_cast<unsigned>(devices.entries.size()) - cpus;
  const unsigned total = threads != 0 ? threads : static_cast<unsigned>(tbb::this_task_arena::max_concurrency());
  const unsigned per_cpu = cpus == 0 ? 0 : std::max(1u, (total > gpus ? total - gpus : 1u) / cpus);
  std::vector<std::unique_ptr<RenderBackend<T>>> made;
  for (int entry : devices.entries) made.push_back(make_one(entry, entry == kCpuDevice ? per_cpu : threads));
  return std::make_unique<MultiBackend<T>>(std::move(made), std::move(remote));
}

#define PT_INSTANTIATE_BACKEND(...)                                                                                                                  \
  template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_backend<__VA_ARGS__>(const std::string&, unsigned, int, Integrator, int);                \
  template std::unique_ptr<RenderBackend<__VA_ARGS__>> make_render_backend<__VA_ARGS__>(const std::string&, const DeviceList&, unsigned, Integrator, \
                                                                                        int, std::vector<std::unique_ptr<BandWorker>>);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_BACKEND)

std::vector<DeviceDescription> describe_devices() {
  std::vector<DeviceDescription> devices{{"cpu", 0, fmt::format("{} hardware threads", tbb::this_task_arena::max_concurrency())}};
#if PT_HAVE_CUDA
  for (DeviceDescription& d : cuda_devices()) devices.push_back(std::move(d));
#else
  devices.push_back({"cuda", -1, "not built"});
#endif
#if PT_HAVE_SYCL
  for (DeviceDescription& d : sycl_devices()) devices.push_back(std::move(d));
#else
  devices.push_back({"sycl", -1, "not built"});
#endif
#if PT_HAVE_RTL
  devices.push_back({"rtl", -1, "the traversal engine's cycle-accurate model, fixed point: " + rtl_formats()});
#else
  devices.push_back({"rtl", -1, "not built"});
#endif
  return devices;
}

void list_devices() {
  // The host's processor is one device of its backend: no index is printed for it.
  for (const DeviceDescription& d : describe_devices())
    fmt::print("{}{}: {}\n", d.backend, d.index >= 0 && d.backend != "cpu" ? fmt::format(" {}", d.index) : "", d.name);
}

}  // namespace pt
