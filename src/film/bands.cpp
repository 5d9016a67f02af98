// The band scheduler: a shared counter of bands, one thread for each worker.
#include "film/bands.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "base/errors.hpp"

namespace pt {

u32 min_band_rows(u32 height, std::size_t workers) {
  if (workers <= 1) return std::max(height, 1u);
  return static_cast<u32>(std::max<u64>(1, height / (32 * static_cast<u64>(workers))));
}

void render_bands(std::span<BandWorker* const> workers, u32 width, const BandWork& work, std::span<FilmPixel> film, u32 min_rows,
                  std::span<u64> shares) {
  if (workers.empty()) throw BackendError("no device to render on");
  if (film.size() != static_cast<std::size_t>(width) * work.row_count) throw BackendError("a film of the wrong size for its bands");
  if (work.row_count == 0 || work.sample_count == 0) return;
  min_rows = std::clamp(min_rows, 1u, work.row_count);
  std::mutex cursor_mutex;
  u32 cursor = 0;  // rows of `work` handed out so far
  // The next band's first row (within `work`) and rows; no rows once all are out.
  const auto take = [&]() -> std::pair<u32, u32> {
    const std::lock_guard lock(cursor_mutex);
    const u32 left = work.row_count - cursor;
    const u64 share = (static_cast<u64>(left) + 2 * workers.size() - 1) / (2 * workers.size());
    const u32 rows = static_cast<u32>(std::min<u64>(left, std::max<u64>(min_rows, share)));
    const u32 first = cursor;
    cursor += rows;
    return {first, rows};
  };
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto drive = [&](std::size_t w) {
    try {
      for (auto [first, rows] = take(); rows > 0 && !failed.load(); std::tie(first, rows) = take()) {
        BandWork part = work;
        part.first_row = work.first_row + first;
        part.row_count = rows;
        workers[w]->render_band(part, film.subspan(static_cast<std::size_t>(first) * width, static_cast<std::size_t>(rows) * width));
        shares[w] += static_cast<u64>(rows) * width * part.sample_count;
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
