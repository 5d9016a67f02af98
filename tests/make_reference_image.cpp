// Regenerates the stored reference image and per-pixel variance that test_reference_image.cpp compares against.
//
// It renders scenes/tiny.json at 4096 samples per pixel, in double precision, with a seed no test renders with, and
// writes the image and the per-sample variance of each pixel. Run it after a change that is meant to change the
// expected image (the test is statistical, so new sampling or random streams with the same expectation need no new
// reference):
//
//   cmake --build build/<folder> --target pt_make_reference_image
//   build/<folder>/tests/pt_make_reference_image
//
// It writes tests/data/tiny-reference.pfm and tests/data/tiny-reference-variance.pfm in the source tree (two optional
// arguments name other files instead) and takes a few seconds on two cores.
#include <cstdio>
#include <exception>
#include <filesystem>

#include "test_support.hpp"

int main(int argc, char** argv) {
  using namespace pt;
  try {
    const std::filesystem::path image_path = argc > 1 ? std::filesystem::path(argv[1]) : test::reference_image_path();
    const std::filesystem::path variance_path = argc > 2 ? std::filesystem::path(argv[2]) : test::reference_variance_path();
    const FlatScene<double> scene = test::tiny_reference_scene<double>(test::kReferenceSamples, test::kReferenceSeed);
    // The image as the renderer makes it, and the variance from the very same samples.
    const RenderResult result = test::render(scene, 0);
    const test::PixelStatistics stats = test::sample_statistics(scene, test::kReferenceSamples);
    if (result.stats.dropped_samples != 0 || stats.non_finite != 0) {
      std::fprintf(stderr, "pt_make_reference_image: non-finite samples; not writing a reference\n");
      return 1;
    }
    LinearImage variance = result.image;
    for (std::size_t i = 0; i < variance.rgb.size(); ++i) variance.rgb[i] = static_cast<float>(stats.variance[i]);
    for (const auto& path : {image_path, variance_path})
      if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
    write_image(image_path, result.image);
    write_image(variance_path, variance);
    std::fprintf(stderr, "wrote %s and %s (%ux%u, %u spp)\n", image_path.string().c_str(), variance_path.string().c_str(), result.image.width,
                 result.image.height, test::kReferenceSamples);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pt_make_reference_image: %s\n", e.what());
    return 1;
  }
}
