// The band scheduler: a shared counter of bands, one thread for each worker.
#include "backends/bands.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "base/errors.hpp"

namespace pt {

u32 min_band_rows(u32 height, std::size_t workers) {
  if (workers <= 1) return std::max(height, 1u);
  return static_cast<u32>(std::max<u64>(1, height / (32 * static_cast<u64>(workers))));
}

bool render_bands(std::span<BandWorker* const> workers, u32 width, const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into,
                  u32 min_rows, std::span<u64> shares, std::span<double> row_costs, const PassStop& stop) {
  if (workers.empty()) throw BackendError("no device to render on");
  const std::size_t pixels = static_cast<std::size_t>(width) * work.row_count;
  if (from.size() != pixels || into.size() != pixels) throw BackendError("a film of the wrong size for its bands");
  if (work.row_count == 0 || work.sample_count == 0) {
    if (from.data() != into.data()) std::copy(from.begin(), from.end(), into.begin());
    return true;
  }
  min_rows = std::clamp(min_rows, 1u, work.row_count);
  // The rows' costs as the last pass measured them, summed from the first row of `work` (cost[i]: rows before i);
  // none where a row has not been measured yet, and the bands are cut by rows instead.
  std::vector<double> cost;
  if (row_costs.size() >= static_cast<std::size_t>(work.first_row) + work.row_count) {
    cost.assign(work.row_count + 1, 0.0);
    for (u32 i = 0; i < work.row_count && !cost.empty(); ++i) {
      const double row = row_costs[work.first_row + i];
      if (row > 0)
        cost[i + 1] = cost[i] + row;
      else
        cost.clear();
    }
  }
  const u64 halves = 2 * static_cast<u64>(workers.size());
  const std::function<bool()> stopping = stop.requested ? stop.requested : [] { return false; };
  std::atomic<bool> failed{false}, given_up{false};
  std::mutex cursor_mutex;
  std::condition_variable band_back;          // a band came back, or one fewer is out
  u32 cursor = 0;                             // rows of `work` handed out so far
  u32 out = 0;                                // bands handed out and not yet back
  std::vector<std::pair<u32, u32>> returned;  // bands of lost workers, to hand out again
  // The next band's first row (within `work`) and rows; no rows once all are out and back. A band a lost worker
  // gave back first; else half of an even share of what is left: of its cost where that is known, else of its
  // rows; `bounded`: no longer than the stop allows. With nothing left to hand out while bands are still out, waits:
  // one may come back.
  const auto take = [&](bool bounded) -> std::pair<u32, u32> {
    std::unique_lock lock(cursor_mutex);
    while (returned.empty() && cursor == work.row_count && out > 0 && !failed.load() && !stopping())
      band_back.wait_for(lock, std::chrono::milliseconds(10));
    if (!returned.empty()) {
      const std::pair<u32, u32> band = returned.back();
      returned.pop_back();
      ++out;
      return band;
    }
    const u32 left = work.row_count - cursor;
    if (left == 0) return {0, 0};
    u64 share = (static_cast<u64>(left) + halves - 1) / halves;
    if (!cost.empty()) {
      const double target = cost[cursor] + (cost[work.row_count] - cost[cursor]) / static_cast<double>(halves);
      const auto end = std::lower_bound(cost.begin() + cursor + 1, cost.end(), target);
      share = static_cast<u64>(std::min<std::ptrdiff_t>(end - cost.begin(), work.row_count) - cursor);
    }
    u32 rows = static_cast<u32>(std::min<u64>(left, std::max<u64>(min_rows, share)));
    if (bounded && stop.longest_band_seconds > 0 && !cost.empty()) {
      // The rows from the cursor whose cost together is within the bound (one at least).
      const double most = cost[cursor] + stop.longest_band_seconds / work.sample_count;
      const auto beyond = std::upper_bound(cost.begin() + cursor + 1, cost.end(), most);
      rows = std::min(rows, std::max<u32>(1, static_cast<u32>(beyond - cost.begin() - 1) - cursor));
    }
    const u32 first = cursor;
    cursor += rows;
    ++out;
    return {first, rows};
  };
  // A band is back: rendered (or left on a stop), or given back by a lost worker.
  const auto back = [&](std::optional<std::pair<u32, u32>> again) {
    const std::lock_guard lock(cursor_mutex);
    --out;
    if (again) returned.push_back(*again);
    band_back.notify_all();
  };
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto drive = [&](std::size_t w) {
    if (workers[w]->lost()) return;
    try {
      while (!failed.load() && !stopping()) {
        const auto [first, rows] = take(!workers[w]->leaves_bands());
        if (rows == 0) break;
        BandWork part = work;
        part.first_row = work.first_row + first;
        part.row_count = rows;
        part.expected_seconds = cost.empty() ? 0.0 : (cost[first + rows] - cost[first]) * part.sample_count;
        const auto start = std::chrono::steady_clock::now();
        const std::size_t offset = static_cast<std::size_t>(first) * width, size = static_cast<std::size_t>(rows) * width;
        bool rendered = false;
        try {
          rendered = workers[w]->render_band(part, from.subspan(offset, size), into.subspan(offset, size), stopping);
        } catch (const WorkerLost&) {
          back(std::pair{first, rows});
          return;
        } catch (...) {
          back(std::nullopt);
          throw;
        }
        back(std::nullopt);
        if (!rendered) {
          given_up = true;
          break;
        }
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
  if (!returned.empty() && !given_up.load() && !stopping()) throw BackendError("every device of the run stopped answering");
  return cursor == work.row_count && returned.empty() && !given_up.load();
}

}  // namespace pt
