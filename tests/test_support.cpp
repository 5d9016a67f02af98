// The test helpers that trace paths themselves, compiled once with the libraries' optimisation rather than in every
// test file that uses them (test_support.hpp).
#include "test_support.hpp"

namespace pt::test {

template <class T>
PixelStatistics sample_statistics(const FlatScene<T>& scene, u32 samples) {
  PixelStatistics stats = PixelStatistics::zeros(scene.params.width, scene.params.height, samples);
  std::atomic<u64> non_finite{0};
  const SceneView<T> view = scene.view();
  ParallelLoop loop(std::max(1u, std::thread::hardware_concurrency()));
  loop.run(stats.height, 1, [&](u32 y) {
    for (u32 x = 0; x < stats.width; ++x) {
      double mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
      u32 count = 0;
      for (u32 s = 0; s < samples; ++s) {
        const Color<T> c = trace_sample(view, x, y, s).radiance;
        if (!is_finite(c)) {
          ++non_finite;
          continue;
        }
        ++count;
        const double value[3] = {static_cast<double>(c.x), static_cast<double>(c.y), static_cast<double>(c.z)};
        for (int k = 0; k < 3; ++k) {  // Welford's update
          const double delta = value[k] - mean[k];
          mean[k] += delta / count;
          m2[k] += delta * (value[k] - mean[k]);
        }
      }
      const std::size_t i = 3 * (static_cast<std::size_t>(y) * stats.width + x);
      for (int k = 0; k < 3; ++k) {
        stats.mean[i + k] = mean[k];
        stats.variance[i + k] = count > 1 ? m2[k] / (count - 1) : 0.0;
      }
    }
  });
  stats.non_finite = non_finite;
  return stats;
}

template PixelStatistics sample_statistics<float>(const FlatScene<float>&, u32);
template PixelStatistics sample_statistics<double>(const FlatScene<double>&, u32);

}  // namespace pt::test
