// Bands of an image's rows handed out to several renderers as each becomes free: the one scheduler behind the
// devices of one process and the processes of an MPI run (docs/distributed.md).
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>

#include "kernel/integrator.hpp"

namespace pt {

// Samples [first_sample, first_sample + sample_count) of every pixel of rows [first_row, first_row + row_count).
struct BandWork {
  u32 first_row = 0, row_count = 0;
  u32 first_sample = 0, sample_count = 0;
  double expected_seconds = 0;  // what its rows took when last rendered, by whichever worker; 0: not known
};

// Thrown by render_band when a worker gives its band up because it stopped answering (an MPI rank that died or
// stalls): render_bands hands the band to the other workers, and the worker is lost() from then on.
class WorkerLost : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Something that renders bands: a device's backend in this process, or another process of an MPI run.
class BandWorker {
 public:
  virtual ~BandWorker() = default;
  virtual std::string name() const = 0;
  // Writes to `into` the film of the band's rows (row-major, the band's first row first) with the samples of `work`
  // added to `from`, the film of those rows so far: each pixel goes on from its sums, in sample order, so the
  // result does not depend on which worker renders it. `from` and `into` are the same rows or do not overlap.
  // A worker that waits for the band elsewhere may leave it when `stop` turns true and return false, with `into`
  // unwritten; it then deals with the band still under way itself. True: the band is in `into`.
  virtual bool render_band(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>& stop) = 0;
  // Whether render_band can leave a band on a stop (a worker waiting for it elsewhere); a device of this process
  // cannot.
  virtual bool leaves_bands() const { return false; }
  // Whether the worker has stopped answering (render_band threw WorkerLost): it is given no more bands.
  virtual bool lost() const { return false; }
};

// How the pass render_bands renders may be given up: once `requested` returns true no more bands are handed out
// and workers may leave theirs. The bands of workers that cannot leave them are cut to take at most
// `longest_band_seconds` each (by the rows' costs as last measured; 0: no bound), since such a band holds up the
// stop until it ends.
struct PassStop {
  std::function<bool()> requested;
  double longest_band_seconds = 0;
};

// The smallest band worth handing out when `workers` share `height` rows: one worker takes them all in one band
// (one launch, as without bands); several take bands that shrink as the rows run out (render_bands), down to this
// many rows, a 32nd of an even share, so that the wait for the last band of a pass is short while every band
// stays a launch of many pixels.
u32 min_band_rows(u32 height, std::size_t workers);

// Renders `work` in bands handed out in order to whichever worker is free, each half of an even share of what is
// left (guided self-scheduling: large bands first, few messages; small ones last, a short wait at the end), at
// least `min_rows`: one host thread drives each worker (none when there is one), taking the next band as soon as
// it has finished one. `from` holds the rows of `work` so far, `width` pixels each, and `into` (the same film, or
// another of its size) gets them with the samples added. Adds to shares[i] the pixel-samples that workers[i]
// rendered. `row_costs`, where given, holds the seconds a sample of each row of the image took when last rendered
// (0: not yet): bands are then cut to equal shares of cost rather than of rows, since rows of sky cost a fraction
// of rows of glass and an expensive band handed out early would hold up the end of the pass; each band rendered
// updates its rows. A band whose worker is lost (WorkerLost) goes to the next worker free, and workers that are
// done wait for the bands still out, so that every row is rendered whoever is lost, as long as one worker is left;
// lost workers are given nothing. After a failure no more bands are handed out; the first error is rethrown once
// every worker has stopped. Returns whether every band was rendered: false where `stop` gave the pass up, and then `into` holds
// some rows rendered, some not, and is to be dropped (which is why a pass that may stop needs two films).
bool render_bands(std::span<BandWorker* const> workers, u32 width, const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into,
                  u32 min_rows, std::span<u64> shares, std::span<double> row_costs = {}, const PassStop& stop = {});

}  // namespace pt
