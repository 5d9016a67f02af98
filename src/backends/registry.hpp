// Which backends this build has, and making one by name.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/backend.hpp"
#include "backends/bands.hpp"

namespace pt {

std::vector<std::string> backend_names();
std::string backend_choices();

// "cpu", "cuda", "sycl" or "auto" (the CUDA GPU when one is usable, else the CPU; says which on stderr).
// `device` is the CUDA GPU; `sycl_device` indexes the SYCL devices (negative: the runtime's default choice).
template <class T>
std::unique_ptr<RenderBackend<T>> make_backend(const std::string& name, unsigned threads, int device, Integrator integrator = Integrator::kMegakernel,
                                               int sycl_device = -1);

// What --device names: one device, rendered as ever by its backend alone, or several ("all" or a list, even of
// one device), which render one image in bands (backends/multi_backend.hpp). Entries are device indices of the
// backend (CUDA GPUs, SYCL devices), or kCpuDevice for a CPU device beside them or, with the cpu backend, several
// CPU devices in one process (each with its share of the threads: the tests' stand-in for several GPUs).
inline constexpr int kCpuDevice = -1;
struct DeviceList {
  bool several = false;
  std::vector<int> entries;
};

// Reads --device: an index, "all", "cpu", "local-rank" (the GPU of the process's rank on its node, for MPI runs:
// OMPI_COMM_WORLD_LOCAL_RANK, MPI_LOCALRANKID or SLURM_LOCALID, modulo the GPUs there), or a list of indices and
// "cpu" joined by commas. Throws InputError for anything else.
DeviceList parse_device_list(const std::string& text, const std::string& backend);

// The backend of a DeviceList: the device's own backend for one, else a MultiBackend over one backend per device
// and the `remote` workers (other processes of an MPI run; with any, a MultiBackend even for one device).
template <class T>
std::unique_ptr<RenderBackend<T>> make_render_backend(const std::string& backend, const DeviceList& devices, unsigned threads, Integrator integrator,
                                                      int sycl_device, std::vector<std::unique_ptr<BandWorker>> remote = {});

// Every backend's devices, the host's processor first (backend "cpu", index 0), and a word for each backend built
// without devices here or not built.
std::vector<DeviceDescription> describe_devices();

// Prints describe_devices() to stdout, one a line (`pathtracer devices`).
void list_devices();

}  // namespace pt
