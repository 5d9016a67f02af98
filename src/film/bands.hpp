// Bands of an image's rows handed out to several renderers as each becomes free: the one scheduler behind the
// devices of one process and the processes of an MPI run (docs/distributed.md).
#pragma once

#include <cstddef>
#include <span>
#include <string>

#include "kernel/integrator.hpp"

namespace pt {

// Samples [first_sample, first_sample + sample_count) of every pixel of rows [first_row, first_row + row_count).
struct BandWork {
  u32 first_row = 0, row_count = 0;
  u32 first_sample = 0, sample_count = 0;
  double expected_seconds = 0;  // what its rows took when last rendered, by whichever worker; 0: not known
};

// Something that renders bands: a device's backend in this process, or another process of an MPI run.
class BandWorker {
 public:
  virtual ~BandWorker() = default;
  virtual std::string name() const = 0;
  // Adds the samples of `work` to `band`, the film of its rows (row-major, the band's first row first): each pixel
  // goes on from the sums it holds, in sample order, so the result does not depend on which worker renders it.
  virtual void render_band(const BandWork& work, std::span<FilmPixel> band) = 0;
};

// The smallest band worth handing out when `workers` share `height` rows: one worker takes them all in one band
// (one launch, as without bands); several take bands that shrink as the rows run out (render_bands), down to this
// many rows, a 32nd of an even share, so that the wait for the last band of a pass is short while every band
// stays a launch of many pixels.
u32 min_band_rows(u32 height, std::size_t workers);

// Renders `work` in bands handed out in order to whichever worker is free, each half of an even share of what is
// left (guided self-scheduling: large bands first, few messages; small ones last, a short wait at the end), at
// least `min_rows`: one host thread drives each worker (none when there is one), taking the next band as soon as
// it has finished one. `film` holds the rows of `work`, `width` pixels each. Adds to shares[i] the pixel-samples
// that workers[i] rendered. `row_costs`, where given, holds the seconds a sample of each row of the image took
// when last rendered (0: not yet): bands are then cut to equal shares of cost rather than of rows, since rows of
// sky cost a fraction of rows of glass and an expensive band handed out early would hold up the end of the pass;
// each band rendered updates its rows. After a failure no more bands are handed out; the first error is rethrown
// once every worker has stopped.
void render_bands(std::span<BandWorker* const> workers, u32 width, const BandWork& work, std::span<FilmPixel> film, u32 min_rows,
                  std::span<u64> shares, std::span<double> row_costs = {});

}  // namespace pt
