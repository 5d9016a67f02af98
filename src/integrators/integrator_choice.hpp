// Which integrator traces a render's paths, as the command line and the backends name it.
#pragma once

namespace pt {

// How paths are traced: each in one go (megakernel), or in stages over queues of paths (wavefront); kAuto lets the
// backend take the one its device names as its faster (the megakernel on CPUs and through SYCL, the wavefront
// through CUDA: BENCHMARKS.md). kBidirectional joins light and camera subpaths (bidirectional path tracing,
// kernel/bidirectional.hpp) for light that reaches diffuse surfaces through glass or off mirrors; kVertexMerging adds
// vertex merging to it (VCM), for caustics seen through glass or in mirrors, which no connection can reach.
enum class Integrator { kMegakernel, kWavefront, kAuto, kBidirectional, kVertexMerging };

// The integrator's name as the command line spells it.
inline const char* integrator_name(Integrator integrator) {
  switch (integrator) {
    case Integrator::kMegakernel: return "megakernel";
    case Integrator::kWavefront: return "wavefront";
    case Integrator::kBidirectional: return "bdpt";
    case Integrator::kVertexMerging: return "vcm";
    default: return "auto";
  }
}

}  // namespace pt
