// The environment image's sampling distribution, and the background's mean radiance for light selection.
#include "flat/environment.hpp"

#include <cmath>

#include "base/scalar_types.hpp"
#include "flat/flat_scene.hpp"
#include "kernel/fixed_point.hpp"

namespace pt {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Fills cdf (n + 1 entries) from n non-negative weights summing to `total` > 0. Sums are formed in double and rounded
// once, so the stored CDF never decreases; its ends are exactly 0 and 1.
void cumulate(const double* weights, u32 n, double total, float* cdf) {
  double sum = 0;
  cdf[0] = 0.0f;
  for (u32 i = 0; i < n; ++i) {
    sum += weights[i];
    cdf[i + 1] = static_cast<float>(sum / total);
  }
  cdf[n] = 1.0f;
}

}  // namespace

EnvironmentDistribution environment_distribution(std::span<const float> rgb, u32 width, u32 height) {
  const std::size_t texels = static_cast<std::size_t>(width) * height;
  std::vector<double> weight(texels);
  double total = 0;
  for (int pass = 0; pass < 2 && total == 0; ++pass) {
    for (u32 row = 0; row < height; ++row) {
      const double sin_theta = std::sin(kPi * (row + 0.5) / height);
      for (u32 column = 0; column < width; ++column) {
        const std::size_t i = static_cast<std::size_t>(row) * width + column;
        // The second pass, for a black image: sin(theta) alone.
        const double l = pass == 0 ? luminance(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]) : 1.0;
        weight[i] = l * sin_theta;
        total += weight[i];
      }
    }
  }
  EnvironmentDistribution d;
  d.density.resize(texels);
  d.row_cdf.resize(height + 1);
  d.column_cdfs.resize(static_cast<std::size_t>(height) * (width + 1));
  const double mean = total / static_cast<double>(texels);
  std::vector<double> row_sums(height);
  for (u32 row = 0; row < height; ++row) {
    const double* w = weight.data() + static_cast<std::size_t>(row) * width;
    double sum = 0;
    for (u32 column = 0; column < width; ++column) {
      d.density[static_cast<std::size_t>(row) * width + column] = static_cast<float>(w[column] / mean);
      sum += w[column];
    }
    row_sums[row] = sum;
    float* cdf = d.column_cdfs.data() + static_cast<std::size_t>(row) * (width + 1);
    if (sum > 0) {
      cumulate(w, width, sum, cdf);
    } else {
      // Never drawn (its row has probability 0); uniform, so that the CDF is still one.
      for (u32 column = 0; column <= width; ++column) cdf[column] = static_cast<float>(static_cast<double>(column) / width);
    }
  }
  cumulate(row_sums.data(), height, total, d.row_cdf.data());
  return d;
}

template <class T>
Color<double> background_mean_radiance(const FlatScene<T>& scene) {
  const EnvironmentMap<T>& map = scene.background.environment;
  if (map.width == 0) {
    // Over the sphere the height y is uniform in [-1, 1], so the gradient's mean is its middle.
    const Color<T>& h = scene.background.horizon;
    const Color<T>& z = scene.background.zenith;
    return Color<double>{static_cast<double>(h.x) + static_cast<double>(z.x), static_cast<double>(h.y) + static_cast<double>(z.y),
                         static_cast<double>(h.z) + static_cast<double>(z.z)} *
           0.5;
  }
  // Each texel weighted by its solid angle, (2 pi / width) (cos theta0 - cos theta1).
  Color<double> sum{};
  for (u32 row = 0; row < map.height; ++row) {
    const double solid_angle = 2 * kPi / map.width * (std::cos(kPi * row / map.height) - std::cos(kPi * (row + 1) / map.height));
    Color<double> row_sum{};
    for (u32 column = 0; column < map.width; ++column) {
      const float* t = scene.environment_rgb.data() + 3 * (static_cast<std::size_t>(row) * map.width + column);
      row_sum += Color<double>{t[0], t[1], t[2]};
    }
    sum += row_sum * solid_angle;
  }
  return sum / (4 * kPi);
}

#define PT_INSTANTIATE_BACKGROUND_MEAN(...) template Color<double> background_mean_radiance<__VA_ARGS__>(const FlatScene<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_BACKGROUND_MEAN)

}  // namespace pt
