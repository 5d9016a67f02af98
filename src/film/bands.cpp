// The band scheduler: a shared counter of bands, one thread for each worker.
#include "film/bands.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "base/errors.hpp"

namespace pt {

u32 band_rows_for(u32 height, std::size_t workers) {
  if (workers <= 1) return std::max(height, 1u);
  const u64 bands = std::min<u64>(4 * static_cast<u64>(workers), std::max(height, 1u));
  return static_cast<u32>((height + bands - 1) / bands);
}

void render_bands(std::span<BandWorker* const> workers, u32 width, const BandWork& work, std::span<FilmPixel> film, u32 band_rows,
                  std::span<u64> shares) {
  if (workers.empty()) throw BackendError("no device to render on");
  if (film.size() != static_cast<std::size_t>(width) * work.row_count) throw BackendError("a film of the wrong size for its bands");
  if (work.row_count == 0 || work.sample_count == 0) return;
  band_rows = std::clamp(band_rows, 1u, work.row_count);
  const u32 bands = (work.row_count + band_rows - 1) / band_rows;
  std::atomic<u32> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto drive = [&](std::size_t w) {
    try {
      for (u32 band = next++; band < bands && !failed.load(); band = next++) {
        BandWork part = work;
        part.first_row = work.first_row + band * band_rows;
        part.row_count = std::min(band_rows, work.row_count - band * band_rows);
        const std::size_t offset = static_cast<std::size_t>(band) * band_rows * width;
        workers[w]->render_band(part, film.subspan(offset, static_cast<std::size_t>(part.row_count) * width));
        shares[w] += static_cast<u64>(part.row_count) * width * part.sample_count;
      }
    } catch (...) {
      const std::lock_guard lock(error_mutex);
      if (!first_error) first_error = std::current_exception();
      failed = true;
    }
  };
  if (workers.size() == 1) {
    drive(0);
  } else {
    std::vector<std::thread> threads;
    threads.reserve(workers.size());
    for (std::size_t w = 0; w < workers.size(); ++w) threads.emplace_back(drive, w);
    for (std::thread& t : threads) t.join();
  }
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace pt
