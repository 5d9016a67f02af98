// MPI between the ranks of one render: start-up reports, bands sent out and films sent back, stop. Every wait is
// a test-and-sleep loop rather than a blocking call, whose busy polling would take a core from the renderer.
#include "app/distributed.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
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

void wait_for(MPI_Request& request) {
  for (;;) {
    int done = 0;
    {
      const std::lock_guard lock(mpi_mutex);
      MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    }
    if (done) return;
    std::this_thread::sleep_for(kTransferPoll);
  }
}

// The next message from `source` (MPI_ANY_SOURCE: from anyone) with any tag, not yet received; none where `stop`
// (if given) turns true first.
std::optional<MPI_Status> probe_unless(int source, const std::function<bool()>& stop) {
  for (;;) {
    int found = 0;
    MPI_Status status;
    {
      const std::lock_guard lock(mpi_mutex);
      MPI_Iprobe(source, MPI_ANY_TAG, MPI_COMM_WORLD, &found, &status);
    }
    if (found) return status;
    if (stop && stop()) return std::nullopt;
    std::this_thread::sleep_for(kPoll);
  }
}

MPI_Status probe(int source) { return *probe_unless(source, {}); }

// Byte arrays in pieces of at most 1 GiB, since MPI counts are ints; pieces of one tag arrive in order. `post` is
// MPI_Isend or MPI_Irecv, whose arguments are the same but for the constness of the buffer.
constexpr std::size_t kPiece = std::size_t{1} << 30;

template <class Byte, class Post>
void transfer_in_pieces(Byte* data, std::size_t bytes, int peer, int tag, Post post) {
  do {
    const std::size_t piece = std::min(bytes, kPiece);
    MPI_Request request;
    {
      const std::lock_guard lock(mpi_mutex);
      post(data, static_cast<int>(piece), MPI_BYTE, peer, tag, MPI_COMM_WORLD, &request);
    }
    wait_for(request);
    data += piece;
    bytes -= piece;
  } while (bytes > 0);
}

void send_bytes(const void* data, std::size_t bytes, int destination, int tag) {
  transfer_in_pieces(static_cast<const char*>(data), bytes, destination, tag, MPI_Isend);
}

void receive_bytes(void* data, std::size_t bytes, int source, int tag) {
  transfer_in_pieces(static_cast<char*>(data), bytes, source, tag, MPI_Irecv);
}

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

// Rank 0's view of another rank: bands go out with the film they go on from, and come back rendered.
class RankWorker final : public BandWorker {
 public:
  RankWorker(int rank, std::string where, std::string name) : rank_(rank), where_(std::move(where)), name_(std::move(name)) {}
  // A band left on a stop is still on its way back; the rank takes the stop message only once it is received.
  ~RankWorker() override { receive_band_left(); }
  std::string name() const override { return name_; }
  bool leaves_bands() const override { return true; }
  bool render_band(const BandWork& work, std::span<const FilmPixel> from, std::span<FilmPixel> into, const std::function<bool()>& stop) override {
    receive_band_left();
    message_.resize(1 + from.size());
    std::memcpy(static_cast<void*>(message_.data()), &work, sizeof(work));
    std::copy(from.begin(), from.end(), message_.begin() + 1);
    send_bytes(message_.data(), message_.size() * sizeof(FilmPixel), rank_, kWork);
    // Sleep through most of the time the band should take before polling: this thread shares a core with the
    // renderer of this rank, and thousands of wake-ups a second would slow it. (Where the rows were last rendered
    // by a slower worker, the sleep runs long; ranks of one kind of device are the case this is for.) The sleep is
    // cut into slices that look for a stop.
    using Clock = std::chrono::steady_clock;
    const Clock::time_point wake =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(0.8 * work.expected_seconds));
    while (!stop() && Clock::now() < wake) std::this_thread::sleep_until(std::min(wake, Clock::now() + kStopLook));
    const std::optional<MPI_Status> reply = probe_unless(rank_, stop);
    if (!reply) {
      left_bytes_ = into.size_bytes();
      return false;
    }
    if (reply->MPI_TAG == kFailed) throw RemoteError(fmt::format("{}: {}", where_, receive_text(*reply)));
    receive_bytes(into.data(), into.size_bytes(), rank_, kBandDone);
    return true;
  }

 private:
  // How often a sleep through a band looks for a stop.
  static constexpr auto kStopLook = std::chrono::milliseconds(10);

  // Receives the reply to a band left on a stop, rendered or failed, and drops it.
  void receive_band_left() {
    if (left_bytes_ == 0) return;
    const MPI_Status reply = probe(rank_);
    if (reply.MPI_TAG == kFailed) {
      receive_text(reply);
    } else {
      message_.resize(left_bytes_ / sizeof(FilmPixel));
      receive_bytes(message_.data(), left_bytes_, rank_, kBandDone);
    }
    left_bytes_ = 0;
  }

  int rank_;
  std::string where_, name_;
  std::vector<FilmPixel> message_;
  std::size_t left_bytes_ = 0;  // the size of a band left on a stop and not yet received (0: none)
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
    workers.push_back(std::make_unique<RankWorker>(rank, where(rank), fmt::format("{}: {}", where(rank), names[rank])));
  return workers;
}

void Distributed::stop_all() {
  if (stopped_ || rank_ != 0) return;
  stopped_ = true;
  for (int rank = 1; rank < size_; ++rank) send_bytes(nullptr, 0, rank, kStop);
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
void Distributed::stop_all() {}
void Distributed::report_ready(u64, const std::string&) {}
void Distributed::report_failure(const std::string&) {}
void Distributed::serve(u32, const std::function<void(const BandWork&, std::span<FilmPixel>)>&) {}

#endif

}  // namespace pt
