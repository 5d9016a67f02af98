// What a render is asked for besides the scene: image size, samples, path depth, seed. A scene file gives them,
// the command line overrides them, and flattening hands them to the kernels.
#pragma once

#include "kernel/platform.hpp"

namespace pt {

struct RenderSettings {
  u32 width = 800;
  u32 height = 480;
  u32 samples_per_pixel = 100;
  u32 max_depth = 50;
  u32 seed = 1;
  u32 roulette_depth = 0;
};

}  // namespace pt
