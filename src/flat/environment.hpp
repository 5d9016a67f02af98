// The sampling distribution of an environment image, built on the host for kernel/background.hpp's sampling.
#pragma once

#include <span>
#include <vector>

#include "kernel/platform.hpp"

namespace pt {

// A piecewise-constant distribution over the image's (u, v) square, each texel's weight its luminance times
// sin(theta) at its row's centre: proportional to the power it sends in, since a row's texels cover less solid
// angle nearer the poles. Where the whole image is black the weights are sin(theta) alone (about uniform on the
// sphere), so that sampling stays defined.
struct EnvironmentDistribution {
  std::vector<float> density;      // per texel: weight / mean weight, the density over the (u, v) square
  std::vector<float> row_cdf;      // height + 1 entries: the rows' summed weights, cumulated, from 0 to 1
  std::vector<float> column_cdfs;  // per row, width + 1 entries: its texels' weights cumulated, from 0 to 1
};

// `rgb`: 3 floats a texel, rows from the top, finite and not negative.
EnvironmentDistribution environment_distribution(std::span<const float> rgb, u32 width, u32 height);

// The luminance the distribution follows (Rec. 709 / sRGB primaries): 0 only for black, as every weight is positive.
inline double luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

}  // namespace pt
