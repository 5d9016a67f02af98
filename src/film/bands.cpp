// The band scheduler: a shared counter of bands, one thread for each worker.
#include "film/bands.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
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
                  std::span<u64> shares, std::span<double> row_costs) {
  if (workers.empty()) throw BackendError("no device to render on");
  if (film.size() != static_cast<std::size_t>(width) * work.row_count) throw BackendError("a film of the wrong size for its bands");
  if (work.row_count == 0 || work.sample_count == 0) return;
  min_rows = std::clamp(min_rows, 1u, work.row_count);
  // The rows' costs as the last pass measured them, summed from the first row of `work` (cost[i]: rows before i);
  // none where a row has not been measured yet, and the bands are cut by rows instead.
  std::vector<double> cost;
  if (row_costs.size() >= static_cast<std::size_t>(work.first_row) + work.row_count) {
    cost.assign(work.row_count + 1, 0.0);
    for (u32 i = 0; i < work.row_count && !cost.empty(); ++i) {
      const double row = row_costs[work.first_row + i];
      if (row > 0) cost[i + 1] = cost[i] + row;
      else cost.clear();
    }
  }
  const u64 halves = 2 * static_cast<u64>(workers.size());
  std::mutex cursor_mutex;
  u32 cursor = 0;  // rows of `work` handed out so far
  // The next band's first row (within `work`) and rows; no rows once all are out. Half of an even share of what is
  // left: of its cost where that is known, else of its rows.
  const auto take = [&]() -> std::pair<u32, u32> {
    const std::lock_guard lock(cursor_mutex);
    const u32 left = work.row_count - cursor;
    u64 share = (static_cast<u64>(left) + halves - 1) / halves;
    if (!cost.empty()) {
      const double target = cost[cursor] + (cost[work.row_count] - cost[cursor]) / static_cast<double>(halves);
      const auto end = std::lower_bound(cost.begin() + cursor + 1, cost.end(), target);
      share = static_cast<u64>(std::min<std::ptrdiff_t>(end - cost.begin(), work.row_count) - cursor);
    }
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
        part.expected_seconds = cost.empty() ? 0.0 : (cost[first + rows] - cost[first]) * part.sample_count;
        const auto start = std::chrono::steady_clock::now();
        workers[w]->render_band(part, film.subspan(static_cast<std::size_t>(first) * width, static_cast<std::size_t>(rows) * width));
        shares[w] += static_cast<u64>(rows) * width * part.sample_count;
        // Each row of the band is taken to cost the band's mean (a worker writes only its own band's rows).
        if (!row_costs.empty()) {
          const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          const double per_row = std::max(seconds, 1e-9) / (static_cast<double>(rows) * part.sample_count);
          for (u32 r = part.first_row; r < part.first_row + rows && r < row_costs.size(); ++r) row_costs[r] = per_row;
        }
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
