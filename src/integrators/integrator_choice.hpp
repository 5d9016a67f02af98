// Which integrator traces a render's paths, as the command line and the backends name it.
#pragma once

namespace pt {

// How paths are traced: each in one go (megakernel), or in stages over queues of paths (wavefront); kAuto lets the
// backend take the one its device names as its faster (the megakernel on CPUs and through SYCL, the wavefront
// through CUDA: BENCHMARKS.md).
enum class Integrator { kMegakernel, kWavefront, kAuto };

}  // namespace pt
