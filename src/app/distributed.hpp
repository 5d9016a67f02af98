// One render across the processes of an MPI run (mpirun, srun): rank 0 hands out bands of rows to every rank and
// gathers them into its film; the other ranks render what they are sent (docs/distributed.md).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "backends/bands.hpp"
#include "base/errors.hpp"

namespace pt {

// A failure of another rank, already named by rank and host.
class RemoteError : public BackendError {
 public:
  using BackendError::BackendError;
};

// Whether this process was started by an MPI launcher with other processes (so that a plain run never starts MPI,
// whose start-up without a launcher spawns a daemon).
bool launched_by_mpi();

// Whether this build has MPI.
bool mpi_built_in();

// The processes of the run. Only the thread that made it and the band threads of rank 0 call MPI, one call at a
// time (MPI_THREAD_SERIALIZED).
class Distributed {
 public:
  Distributed(int& argc, char**& argv);  // MPI_Init_thread; throws BackendError where MPI is not built in
  Distributed(const Distributed&) = delete;
  Distributed& operator=(const Distributed&) = delete;
  ~Distributed();  // MPI_Finalize

  int rank() const { return rank_; }
  int size() const { return size_; }
  const std::string& host() const { return host_; }
  // "rank 2 (host node7)", for messages.
  std::string where(int rank) const;

  // Rank 0: waits until every other rank has loaded the scene and is ready (or has failed), and returns a worker
  // for each. `check` is rank 0's key of the scene and settings (film/checkpoint.hpp): a rank that has loaded
  // another scene or settings is refused. Throws RemoteError naming the first rank that failed.
  std::vector<std::unique_ptr<BandWorker>> gather_workers(u64 check);
  // Rank 0: tells every other rank that the run is over (after its end or a failure); a rank lost is not told.
  void stop_all();
  // Rank 0: whether a rank was lost during the render (it died or stopped answering; its bands went to the others).
  bool any_lost() const;
  // Rank 0, once its image is written: where a rank was lost, ends the run for every rank with `status` (MPI_Abort,
  // since MPI_Finalize would wait for the lost rank); else returns, and the destructor finalises.
  void finish(int status);

  // Other ranks: tells rank 0 that this one is ready, with its key and its devices' name, or why it is not.
  void report_ready(u64 check, const std::string& name);
  void report_failure(const std::string& message);
  // Other ranks: renders each band rank 0 sends with `render`, until rank 0 says stop. A band that fails is
  // reported to rank 0, which stops the run.
  void serve(u32 width, const std::function<void(const BandWork&, std::span<FilmPixel>)>& render);

 private:
  int rank_ = 0, size_ = 1;
  std::string host_;
  std::vector<std::string> hosts_;  // rank 0: every rank's host
  bool stopped_ = false;
  mutable std::mutex lost_mutex_;
  std::vector<char> lost_;  // rank 0: per rank, whether it was lost
};

}  // namespace pt
