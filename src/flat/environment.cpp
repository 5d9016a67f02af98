// The environment image's sampling distribution, the background's mean radiance for light selection, and how noisily
// scattering alone finds it (whether sampling it as a light pays).
#include "flat/environment.hpp"

#include <algorithm>
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

// The solid angle of a texel of row `row` of a width x height equirectangular image: (2 pi / width) (cos theta0 -
// cos theta1).
double texel_solid_angle(u32 row, u32 width, u32 height) {
  return 2 * kPi / width * (std::cos(kPi * row / height) - std::cos(kPi * (row + 1) / height));
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
    const double solid_angle = texel_solid_angle(row, map.width, map.height);
    Color<double> row_sum{};
    for (u32 column = 0; column < map.width; ++column) {
      const float* t = scene.environment_rgb.data() + 3 * (static_cast<std::size_t>(row) * map.width + column);
      row_sum += Color<double>{t[0], t[1], t[2]};
    }
    sum += row_sum * solid_angle;
  }
  return sum / (4 * kPi);
}

namespace {

// One patch of the sphere of directions: its centre, its solid angle, and the mean luminance and mean squared
// luminance the background shows over it.
struct BackgroundPatch {
  double x, y, z;
  double solid_angle;
  double mean, mean_square;
};

// The background as at most kPatchRows x 2 kPatchRows patches of latitude and longitude: the gradient sampled at their
// centres, an environment image's texels gathered into blocks (their squares summed, so a sun smaller than a block
// keeps its second moment).
constexpr u32 kPatchRows = 64;

template <class T>
std::vector<BackgroundPatch> background_patches(const FlatScene<T>& scene) {
  const EnvironmentMap<T>& map = scene.background.environment;
  const u32 width = map.width != 0 ? map.width : 2 * kPatchRows, height = map.width != 0 ? map.height : kPatchRows;
  const u32 block_x = (width + 2 * kPatchRows - 1) / (2 * kPatchRows), block_y = (height + kPatchRows - 1) / kPatchRows;
  std::vector<BackgroundPatch> patches;
  for (u32 row0 = 0; row0 < height; row0 += block_y) {
    const u32 row1 = std::min(height, row0 + block_y);
    for (u32 column0 = 0; column0 < width; column0 += block_x) {
      const u32 column1 = std::min(width, column0 + block_x);
      double weight = 0, sum = 0, sum_square = 0;
      for (u32 row = row0; row < row1; ++row) {
        const double texel_angle = texel_solid_angle(row, width, height);
        for (u32 column = column0; column < column1; ++column) {
          double l;
          if (map.width != 0) {
            const float* t = scene.environment_rgb.data() + 3 * (static_cast<std::size_t>(row) * width + column);
            l = luminance(t[0], t[1], t[2]);
          } else {
            // The gradient depends on the height alone: the kernel's own radiance at the row's centre.
            const Color<T> c = background_radiance(scene.background, Vec3<T>{T(0), T(std::cos(kPi * (row + 0.5) / height)), T(0)});
            l = luminance(static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z));
          }
          weight += texel_angle;
          sum += l * texel_angle;
          sum_square += l * l * texel_angle;
        }
      }
      if (!(weight > 0)) continue;
      const double theta = kPi * 0.5 * (row0 + row1) / height, phi = 2 * kPi * 0.5 * (column0 + column1) / width;
      patches.push_back({std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi), weight, sum / weight, sum_square / weight});
    }
  }
  return patches;
}

}  // namespace

template <class T>
double background_scattering_variance(const FlatScene<T>& scene) {
  const std::vector<BackgroundPatch> patches = background_patches(scene);
  // Normals spread evenly over the sphere (a Fibonacci lattice).
  constexpr int kNormals = 64;
  const double golden_turn = kPi * (3 - std::sqrt(5.0));
  double total = 0;
  int counted = 0;
  for (int i = 0; i < kNormals; ++i) {
    const double ny = 1 - (2 * i + 1.0) / kNormals, r = std::sqrt(1 - ny * ny);
    const double nx = r * std::cos(golden_turn * i), nz = r * std::sin(golden_turn * i);
    // Irradiance E = integral of L cos, and the cosine-sampled estimate pi L's second moment, pi integral of L^2 cos.
    double irradiance = 0, second_moment = 0;
    for (const BackgroundPatch& p : patches) {
      const double cosine = p.x * nx + p.y * ny + p.z * nz;
      if (cosine <= 0) continue;
      irradiance += p.mean * cosine * p.solid_angle;
      second_moment += p.mean_square * cosine * p.solid_angle;
    }
    if (!(irradiance > 0)) continue;  // a black hemisphere: scattering finds nothing there, nor would light sampling
    total += std::max(0.0, kPi * second_moment / (irradiance * irradiance) - 1);
    ++counted;
  }
  return counted > 0 ? total / counted : 0;
}

#define PT_INSTANTIATE_BACKGROUND_MEAN(...) template Color<double> background_mean_radiance<__VA_ARGS__>(const FlatScene<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_BACKGROUND_MEAN)
#define PT_INSTANTIATE_BACKGROUND_VARIANCE(...) template double background_scattering_variance<__VA_ARGS__>(const FlatScene<__VA_ARGS__>&);
PT_FOR_EACH_SCALAR_TYPE(PT_INSTANTIATE_BACKGROUND_VARIANCE)

}  // namespace pt
