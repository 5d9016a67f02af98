// `pathtracer numerics`: renders one scene in every number format built in and measures each against double.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "kernel/platform.hpp"

namespace pt {

struct NumericsOptions {
  std::string scene;
  std::string output_folder = "numerics";
  u32 width = 160, height = 120, spp = 16;
  std::optional<u32> depth, seed;
  unsigned threads = 0;
  std::vector<std::string> formats;  // empty: every format built in
  bool trust_model_paths = false;    // model files may name files outside their folder
  bool bidirectional = false;        // bidirectional path tracing instead of the path tracer
};

// Writes numerics.csv, error-vs-bits.svg, one PNG per format and side-by-side.png to the output folder, prints
// the table to stdout and returns the exit status.
int run_numerics(const NumericsOptions& options);

}  // namespace pt
