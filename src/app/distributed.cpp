// MPI between the ranks of one render: start-up reports, bands sent out and films sent back, stop. Every wait is
// a test-and-sleep loop rather than a blocking call, whose busy polling would take a core from the renderer.
#include "app/distributed.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>

#if PT_HAVE_MPI
#include <mpi.h>
#endif

namespace pt {

bool launched_by_mpi() {
  // Open MPI's mpirun (and srun with Open MPI), MPICH's launchers, and srun with a PMI plugin; one process alone
  // renders as ever.
  const auto above_one = [](const char* name) {
    const char* value = std::getenv(name);
    return value && std::atoi(value) > 1;
  };
  return above_one("OMPI_COMM_WORLD_SIZE") || above_one("PMI_SIZE") ||
         ((std::getenv("PMIX_RANK") || std::getenv("PMI_RANK")) && above_one("SLURM_NTASKS"));
}

#if PT_HAVE_MPI

bool mpi_built_in() { return true; }

namespace {

// Message tags.
enum Tag : int { kReady = 1, kFailed, kWork, kBandDone, kStop };

// One MPI call at a time from any thread (MPI_THREAD_SERIALIZED), and waits that sleep between tests: kPoll while
// waiting for a message to arrive, kTransferPoll while one is on its way. A band's film (megabytes) moves in
// fragments, each of which waits for both sides to call into MPI: tested every kPoll, a transfer crawled (about
// 250 MB/s, 12 % of rank 1's time on a 2-core machine); every 10 us it takes a third of that time. Spinning
// instead was slower still where ranks share cores: the spinning rank held the core the other side needed.
std::mutex mpi_mutex;
constexpr auto kPoll = std::chrono::microseconds(200);
constexpr auto kTransferPoll = std::chrono::microseconds(10);

// MPI's errors are returned rather than fatal (MPI_ERRORS_RETURN): one becomes a BackendError naming the call.
void check(int code, const char* call) {
  if (code == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING] = {};
  int length = 0;
  MPI_Error_string(code, text, &length);
  throw BackendError(fmt::format("{} failed: {}", call, std::string(text, static_cast<std::size_t>(std::max(length, 0)))));
}

// A transfer that has not ended by its deadline (the other side died or stalls; MPI may never say so): thrown as
// TransferOverdue, the request left behind, since the run then ends by MPI_Abort (Distributed::finish). Its message
// says what a stalled band says (RankWorker::exchange), so that one line names a stalled rank wherever it stopped.
using Deadline = std::chrono::steady_clock::time_point;
constexpr Deadline kNoDeadline = Deadline::max();

struct TransferOverdue : BackendError {
  using BackendError::BackendError;
};

void wait_for(MPI_Request& request, Deadline deadline, std::chrono::steady_clock::time_point started) {
  for (;;) {
    int done = 0;
    {
      const std::lock_guard lock(mpi_mutex);
      check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "MPI_Test");
    }
    if (done) return;
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline)
      throw TransferOverdue(fmt::format("has not answered for {:.1f} s while a message to or from it was under way",
                                        std::chrono::duration<double>(now - started).count()));
    std::this_thread::sleep_for(kTransferPoll);
  }
}

// The next message from `source` (MPI_ANY_SOURCE: from anyone) with any tag, not yet received; none where `stop`
// (if given) turns true first, or the `deadline` passes.
std::optional<MPI_Status> probe_unless(int source, const std::function<bool()>& stop,
                                       std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max()) {
  for (;;) {
    int found = 0;
    MPI_Status status;
    {
      const std::lock_guard lock(mpi_mutex);
      check(MPI_Iprobe(source, MPI_ANY_TAG, MPI_COMM_WORLD, &found, &status), "MPI_Iprobe");
    }
    if (found) return status;
    if ((stop && stop()) || std::chrono::steady_clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(kPoll);
  }
}

MPI_Status probe(int source) { return *probe_unless(source, {}); }

// Byte arrays in pieces of at most 1 GiB, since MPI counts are ints; pieces of one tag arrive in order. `post` is
// MPI_Isend or MPI_Irecv, whose arguments are the same but for the constness of the buffer.
constexpr std::size_t kPiece = std::size_t{1} << 30;

template <class Byte, class Post>
void transfer_in_pieces(Byte* data, std::size_t bytes, int peer, int tag, Post post, Deadline deadline) {
  const auto started = std::chrono::steady_clock::now();
  do {
    const std::size_t piece = std::min(bytes, kPiece);
    MPI_Request request;
    {
      const std::lock_guard lock(mpi_mutex);
      check(post(data, static_cast<int>(piece), MPI_BYTE, peer, tag, MPI_COMM_WORLD, &request), "sending or receiving a message");
    }
    wait_for(request, deadline, started);
    data += piece;
    bytes -= piece;
  } while (bytes > 0);
}

void send_bytes(const void* data, std::size_t bytes, int destination, int tag, Deadline deadline = kNoDeadline) {
  transfer_in_pieces(static_cast<const char*>(data), bytes, destination, tag, MPI_Isend, deadline);
}

void receive_bytes(void* data, std::size_t bytes, int source, int tag, Deadline deadline = kNoDeadline) {
  transfer_in_pieces(static_cast<char*>(data), bytes, source, tag, MPI_Irecv, deadline);
}

// How long rank 0 gives a band's transfer to or from another rank: kLeastDeadline (below) and a second for every
// 100 MB, far slower than any link between nodes.
Deadline transfer_deadline(std::size_t bytes);

void send_text(const std::string& text, int destination, int tag) { send_bytes(text.data(), text.size(), destination, tag); }

// The text of the message `status` found.
std::string receive_text(const MPI_Status& status) {
  int count = 0;
  {
    const std::lock_guard lock(mpi_mutex);
    MPI_Get_count(&status, MPI_BYTE, &count);
  }
  std::string text(static_cast<std::size_t>(count), '\0');
  receive_bytes(text.data(), text.size(), status.MPI_SOURCE, status.MPI_TAG);
  return text;
}

// A band's work message: the BandWork in the first FilmPixel's place, then the film the band goes on from; one
// message, since every message costs a wait on each side.
static_assert(sizeof(BandWork) <= sizeof(FilmPixel));

// How long rank 0 waits for a band before it takes the rank for lost: kDeadlineFactor times what the band's rows
// took when last rendered, at least kLeastDeadline (for scheduling noise on a loaded node); a band whose rows have
// not been rendered yet (the first pass) gets kFirstDeadline.
constexpr double kDeadlineFactor = 8;
constexpr double kLeastDeadline = 5;
constexpr double kFirstDeadline = 60;

Deadline transfer_deadline(std::size_t bytes) {
  return std::chrono::steady_clock::now() +
         std::chrono::duration_cast<Deadline::duration>(std::chrono::duration<double>(kLeastDeadline + static_cast<double>(bytes) / 1e8));
}

// Rank 0's view of another rank: bands go out with the film they go on from, and come back rendered. A rank that
// does not answer by its band's deadline, or whose messages fail, is lost: its band goes to the others, and the
// run ends without waiting for it (Distributed::finish).
class RankWorker final : public BandWorker {
 public:
  RankWorker(int rank, std::string where, std::string name, std::function<void(int)> on_lost)
      : rank_(rank), where_(std::move(where)), name_(std::move(name)), on_lost_(std::move(on_lost)) {}
  // A band left on a stop is still on its way back; the rank takes the stop message only once it is received.
  ~RankWorker() override {
    if (!lost_) receive_band_left();
  }
  std::string name() const override { return name_; }
  bool leaves_bands() const override { return true; }
  bool lost() const override { return lost_; }
  bool render_band(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>& stop) override {
    try {
      return exchange(work, from, into, stop);
    } catch (const RemoteError&) {
      throw;
    } catch (const WorkerLost&) {
      throw;
    } catch (const TransferOverdue& e) {  // stalled or dead while a band was on its way
      lose(e.what());
    } catch (const std::exception& e) {  // an MPI call that failed: the rank is gone
      lose(fmt::format("is lost ({})", e.what()));
    }
  }

 private:
  // How often a sleep through a band looks for a stop.
  static constexpr auto kStopLook = std::chrono::milliseconds(10);

  [[noreturn]] void lose(const std::string& what) {
    lost_ = true;
    left_bytes_ = 0;
    on_lost_(rank_);
    fmt::print(stderr, "\npathtracer: warning: {} {}; the other ranks render its rows\n", where_, what);
    throw WorkerLost(where_ + ": " + what);
  }

  bool exchange(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>& stop) {
    receive_band_left();
    message_.resize(1 + from.size());
    std::memcpy(static_cast<void*>(message_.data()), &work, sizeof(work));
    std::copy(from.begin(), from.end(), message_.begin() + 1);
    using Clock = std::chrono::steady_clock;
    const Clock::time_point sent = Clock::now();
    send_bytes(message_.data(), message_.size() * sizeof(FilmPixel), rank_, kWork, transfer_deadline(message_.size() * sizeof(FilmPixel)));
    // Sleep through most of the time the band should take before polling: this thread shares a core with the
    // renderer of this rank, and thousands of wake-ups a second would slow it. (Where the rows were last rendered
    // by a slower worker, the sleep runs long; ranks of one kind of device are the case this is for.) The sleep is
    // cut into slices that look for a stop.
    const auto after = [&](double seconds) { return sent + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)); };
    const Clock::time_point wake = after(0.8 * work.expected_seconds);
    while (!stop() && Clock::now() < wake) std::this_thread::sleep_until(std::min(wake, Clock::now() + kStopLook));
    const double allowed = work.expected_seconds > 0 ? std::max(kLeastDeadline, kDeadlineFactor * work.expected_seconds) : kFirstDeadline;
    const std::optional<MPI_Status> reply = probe_unless(rank_, stop, after(allowed));
    if (!reply) {
      if (stop()) {
        left_bytes_ = into.size_bytes();
        return false;
      }
      lose(work.expected_seconds > 0
               ? fmt::format("has not answered for {:.1f} s, where its band's rows took {:.2f} s before", allowed, work.expected_seconds)
               : fmt::format("has not answered for {:.0f} s", allowed));
    }
    if (reply->MPI_TAG == kFailed) throw RemoteError(fmt::format("{}: {}", where_, receive_text(*reply)));
    receive_bytes(into.data(), into.size_bytes(), rank_, kBandDone, transfer_deadline(into.size_bytes()));
    return true;
  }

  // Receives the reply to a band left on a stop, rendered or failed, and drops it.
  void receive_band_left() {
    if (left_bytes_ == 0) return;
    const std::optional<MPI_Status> found =
        probe_unless(rank_, {},
                     std::chrono::steady_clock::now() +
                         std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(kFirstDeadline)));
    if (!found) {  // it never came: the rank is lost, and the run ends without it
      lost_ = true;
      left_bytes_ = 0;
      on_lost_(rank_);
      return;
    }
    const MPI_Status reply = *found;
    if (reply.MPI_TAG == kFailed) {
      receive_text(reply);
    } else {
      message_.resize(left_bytes_ / sizeof(FilmPixel));
      try {
        receive_bytes(message_.data(), left_bytes_, rank_, kBandDone, transfer_deadline(left_bytes_));
      } catch (const BackendError&) {
        lost_ = true;
        on_lost_(rank_);
      }
    }
    left_bytes_ = 0;
  }

  int rank_;
  std::string where_, name_;
  std::function<void(int)> on_lost_;
  std::vector<FilmPixel> message_;
  std::size_t left_bytes_ = 0;  // the size of a band left on a stop and not yet received (0: none)
  bool lost_ = false;
};

}  // namespace

Distributed::Distributed(int& argc, char**& argv) {
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  char name[256] = {};
  gethostname(name, sizeof(name) - 1);
  host_ = name;
  if (provided < MPI_THREAD_SERIALIZED) throw BackendError("the MPI library does not allow calls from several threads, one at a time");
  // A failed call returns its error (a rank that died), which rank 0 takes as that rank lost, instead of aborting.
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  lost_.assign(static_cast<std::size_t>(size_), 0);
}

Distributed::~Distributed() { MPI_Finalize(); }

std::string Distributed::where(int rank) const {
  const std::string& host = rank == rank_ ? host_ : rank < static_cast<int>(hosts_.size()) ? hosts_[rank] : std::string("?");
  return fmt::format("rank {} (host {})", rank, host);
}

// A ready report: "check\nhost\nname"; a failure: "host\nmessage".
std::vector<std::unique_ptr<BandWorker>> Distributed::gather_workers(u64 check) {
  hosts_.assign(static_cast<std::size_t>(size_), "?");
  hosts_[0] = host_;
  std::vector<std::string> names(static_cast<std::size_t>(size_));
  for (int reported = 1; reported < size_; ++reported) {
    const MPI_Status status = probe(MPI_ANY_SOURCE);
    const int rank = status.MPI_SOURCE;
    const std::string text = receive_text(status);
    const std::size_t first = text.find('\n');
    if (status.MPI_TAG == kFailed) {
      hosts_[rank] = text.substr(0, first);
      throw RemoteError(fmt::format("{}: {}", where(rank), first == std::string::npos ? text : text.substr(first + 1)));
    }
    const std::size_t second = text.find('\n', first + 1);
    hosts_[rank] = text.substr(first + 1, second - first - 1);
    names[rank] = text.substr(second + 1);
    if (std::strtoull(text.substr(0, first).c_str(), nullptr, 16) != check)
      throw RemoteError(fmt::format("{}: has another scene file or other settings than rank 0 (every rank must render the same)", where(rank)));
  }
  std::vector<std::unique_ptr<BandWorker>> workers;
  for (int rank = 1; rank < size_; ++rank)
    workers.push_back(std::make_unique<RankWorker>(rank, where(rank), fmt::format("{}: {}", where(rank), names[rank]), [this](int lost) {
      const std::lock_guard lock(lost_mutex_);
      lost_[static_cast<std::size_t>(lost)] = 1;
    }));
  return workers;
}

bool Distributed::any_lost() const {
  const std::lock_guard lock(lost_mutex_);
  return std::ranges::find(lost_, 1) != lost_.end();
}

void Distributed::stop_all() {
  if (stopped_ || rank_ != 0) return;
  stopped_ = true;
  for (int rank = 1; rank < size_; ++rank)
    if (!lost_[static_cast<std::size_t>(rank)]) {
      try {
        send_bytes(nullptr, 0, rank, kStop, transfer_deadline(0));
      } catch (const BackendError&) {  // gone since its last band: ended with the others by finish
        const std::lock_guard lock(lost_mutex_);
        lost_[static_cast<std::size_t>(rank)] = 1;
      }
    }
}

void Distributed::finish(int status) {
  // MPI_Finalize waits for every rank, a lost one too: the run is ended for all, with rank 0's status, instead.
  if (rank_ == 0 && any_lost()) {
    std::fflush(stdout);
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, status);
  }
}

void Distributed::report_ready(u64 check, const std::string& name) { send_text(fmt::format("{:x}\n{}\n{}", check, host_, name), 0, kReady); }

void Distributed::report_failure(const std::string& message) { send_text(fmt::format("{}\n{}", host_, message), 0, kFailed); }

void Distributed::serve(u32 width, const std::function<void(const BandWork&, std::span<FilmPixel>)>& render) {
  std::vector<FilmPixel> message;
  for (;;) {
    const MPI_Status status = probe(0);
    if (status.MPI_TAG == kStop) {
      receive_bytes(nullptr, 0, 0, kStop);
      return;
    }
    // The message's first piece tells the band's size; a band of more than one piece has the rest to come.
    int first_piece = 0;
    {
      const std::lock_guard lock(mpi_mutex);
      MPI_Get_count(&status, MPI_BYTE, &first_piece);
    }
    message.resize(static_cast<std::size_t>(first_piece) / sizeof(FilmPixel));
    receive_bytes(message.data(), message.size() * sizeof(FilmPixel), 0, kWork);
    BandWork work;
    std::memcpy(&work, static_cast<const void*>(message.data()), sizeof(work));
    const std::size_t received = message.size(), pixels = static_cast<std::size_t>(work.row_count) * width;
    message.resize(1 + pixels);
    if (message.size() > received) receive_bytes(message.data() + received, (message.size() - received) * sizeof(FilmPixel), 0, kWork);
    const std::span<FilmPixel> band(message.data() + 1, pixels);
    std::string failure;
    try {
      render(work, band);
    } catch (const std::bad_alloc&) {
      failure = "out of memory";
    } catch (const std::exception& e) {
      failure = e.what();
    }
    if (failure.empty())
      send_bytes(band.data(), band.size_bytes(), 0, kBandDone);
    else
      send_text(failure, 0, kFailed);
  }
}

#else  // no MPI in this build

bool mpi_built_in() { return false; }

Distributed::Distributed(int&, char**&) {
  throw BackendError("started by an MPI launcher, but this build has no MPI (configure with -DPT_MPI=ON and libopenmpi-dev)");
}
Distributed::~Distributed() = default;
std::string Distributed::where(int rank) const { return fmt::format("rank {}", rank); }
std::vector<std::unique_ptr<BandWorker>> Distributed::gather_workers(u64) { return {}; }
bool Distributed::any_lost() const { return false; }
void Distributed::stop_all() {}
void Distributed::finish(int) {}
void Distributed::report_ready(u64, const std::string&) {}
void Distributed::report_failure(const std::string&) {}
void Distributed::serve(u32, const std::function<void(const BandWork&, std::span<FilmPixel>)>&) {}

#endif

}  // namespace pt
