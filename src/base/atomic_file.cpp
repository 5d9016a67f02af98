// Files written whole or not at all: a temporary beside the target, checked writes, fsync, close, rename.
#include "base/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <random>
#include <utility>

#include <fmt/format.h>

#include "base/errors.hpp"

namespace pt {
namespace {

constexpr std::size_t kBufferBytes = 1u << 20;

struct InjectedFailure {
  std::atomic<FileStep> step{FileStep::kNone};
  std::atomic<int> error{0};
  std::atomic<std::uint64_t> bytes_left{0};
};
InjectedFailure injected;

// The error a step should fail with by injection, or 0. For writes, `bytes` are about to be written.
int injected_error(FileStep step, std::uint64_t bytes = 0) {
  if (injected.step.load() != step) return 0;
  if (step == FileStep::kWrite) {
    std::uint64_t left = injected.bytes_left.load();
    while (left >= bytes)
      if (injected.bytes_left.compare_exchange_weak(left, left - bytes)) return 0;
  }
  return injected.error.load();
}

// The temporaries that exist now, by path, where a signal handler can reach them: a fixed table of plain buffers
// (no allocation, no locks), a slot claimed with an atomic flag.
constexpr int kTemporarySlots = 16;
struct TemporarySlot {
  std::atomic<bool> used{false};
  char path[4096];
};
TemporarySlot temporary_slots[kTemporarySlots];

int register_temporary(const std::string& path) {
  if (path.size() >= sizeof(TemporarySlot::path)) return -1;
  for (int i = 0; i < kTemporarySlots; ++i) {
    bool expected = false;
    if (temporary_slots[i].used.load() || !temporary_slots[i].used.compare_exchange_strong(expected, true)) continue;
    std::memcpy(temporary_slots[i].path, path.c_str(), path.size() + 1);
    return i;
  }
  return -1;  // more files open at once than slots: that one is not removed by a second interrupt
}

void unregister_temporary(int slot) {
  if (slot >= 0) temporary_slots[slot].used.store(false);
}

}  // namespace

void remove_temporaries_now() noexcept {
  for (TemporarySlot& slot : temporary_slots)
    if (slot.used.load()) ::unlink(slot.path);
}

void inject_file_failure(FileStep step, int error, std::uint64_t after_bytes) {
  injected.error = error;
  injected.bytes_left = after_bytes;
  injected.step = step;
}

std::filesystem::path written_path(const std::filesystem::path& path) {
  std::filesystem::path resolved = path;
  std::error_code error;
  for (int links = 0; links < 40 && std::filesystem::is_symlink(resolved, error); ++links) {
    const std::filesystem::path next = std::filesystem::read_symlink(resolved, error);
    if (error) break;
    resolved = next.is_absolute() ? next : resolved.parent_path() / next;
  }
  return resolved;
}

AtomicFile::AtomicFile(std::filesystem::path target, std::string what) : target_(written_path(target)), what_(std::move(what)) {
  std::filesystem::path folder = target_.parent_path();
  if (folder.empty()) folder = ".";
  // Hidden, unique to this process and call, and with the target's extension (for whoever finds a stray one).
  std::random_device entropy;
  temporary_ = folder / fmt::format(".{}.{}-{:08x}.tmp{}", target_.filename().string(), getpid(), entropy(), target_.extension().string());
  // O_EXCL: never write through a file (or a link) that someone else put there. Mode 0666 less the umask, as
  // any new file gets; the rename keeps it.
  const int injected_create = injected_error(FileStep::kCreate);
  fd_ = injected_create ? -1 : ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd_ < 0) {
    const int error = injected_create ? injected_create : errno;
    throw InputError(
        fmt::format("{}: cannot write {}: cannot create a file in '{}': {}", target_.string(), what_, folder.string(), std::strerror(error)));
  }
  temporary_slot_ = register_temporary(temporary_.string());
  buffer_.reserve(kBufferBytes);
}

AtomicFile::AtomicFile(AtomicFile&& other) noexcept
    : target_(std::move(other.target_)),
      temporary_(std::move(other.temporary_)),
      what_(std::move(other.what_)),
      fd_(std::exchange(other.fd_, -1)),
      buffer_(std::move(other.buffer_)),
      position_(other.position_),
      failure_(std::move(other.failure_)),
      published_(std::exchange(other.published_, true)),
      temporary_slot_(std::exchange(other.temporary_slot_, -1)) {}

AtomicFile::~AtomicFile() {
  if (!published_) remove_temporary();
  unregister_temporary(temporary_slot_);
}

void AtomicFile::remove_temporary() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
  unregister_temporary(std::exchange(temporary_slot_, -1));
}

void AtomicFile::fail(const std::string& reason) {
  if (failure_.empty()) failure_ = reason;
  remove_temporary();
  throw InputError(fmt::format("{}: cannot write {}: {}", target_.string(), what_, failure_));
}

void AtomicFile::write(const void* data, std::size_t bytes) {
  if (!failure_.empty() || fd_ < 0) fail(failure_.empty() ? "the file is already closed" : failure_);
  const char* from = static_cast<const char*>(data);
  if (buffer_.size() + bytes > kBufferBytes) flush_buffer();
  if (bytes >= kBufferBytes)
    write_all(from, bytes);  // large writes go out at once, uncopied
  else
    buffer_.insert(buffer_.end(), from, from + bytes);
  position_ += bytes;
}

void AtomicFile::flush_buffer() {
  write_all(buffer_.data(), buffer_.size());
  buffer_.clear();
}

// Every byte written or an error: write() may write less than asked (signals, some file systems), and a short
// write with no error is followed by the call that reports it (ENOSPC).
void AtomicFile::write_all(const char* data, std::size_t bytes) {
  std::size_t done = 0;
  while (done < bytes) {
    const std::size_t chunk = bytes - done;
    if (const int error = injected_error(FileStep::kWrite, chunk)) fail(std::strerror(error));
    const ssize_t written = ::write(fd_, data + done, chunk);
    if (written < 0 && errno == EINTR) continue;
    if (written < 0) fail(std::strerror(errno));
    done += static_cast<std::size_t>(written);
  }
}

void AtomicFile::seek(std::uint64_t offset) {
  if (!failure_.empty() || fd_ < 0) fail(failure_.empty() ? "the file is already closed" : failure_);
  flush_buffer();
  if (::lseek(fd_, static_cast<off_t>(offset), SEEK_SET) < 0) fail(std::strerror(errno));
  position_ = offset;
}

void AtomicFile::finish() {
  if (!failure_.empty()) fail(failure_);
  if (fd_ < 0) return;  // finished already
  flush_buffer();
  // fsync before the rename: otherwise a crash soon after could leave the new name on a file whose data never
  // reached the disk, and some file systems report a full disk (or an I/O error) only here or at close.
  const int sync_error = injected_error(FileStep::kSync);
  if (sync_error || ::fsync(fd_) != 0) fail(std::strerror(sync_error ? sync_error : errno));
  const int close_error = injected_error(FileStep::kClose);
  const int closed = ::close(fd_);
  fd_ = -1;  // closed even when close() reports an error; the descriptor must not be closed again
  if (close_error || closed != 0) fail(std::strerror(close_error ? close_error : errno));
}

void AtomicFile::publish() {
  finish();
  const int rename_error = injected_error(FileStep::kRename);
  if (rename_error || ::rename(temporary_.c_str(), target_.c_str()) != 0) fail(std::strerror(rename_error ? rename_error : errno));
  published_ = true;
  unregister_temporary(std::exchange(temporary_slot_, -1));
  // The new name made durable as well. Best effort: the file is in place already, and a folder that cannot be
  // opened or synced changes nothing about its content.
  std::filesystem::path folder = target_.parent_path();
  if (folder.empty()) folder = ".";
  if (const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

AtomicFile write_file_unpublished(const std::filesystem::path& target, const std::string& what, const std::string& content) {
  AtomicFile file(target, what);
  file.write(content);
  file.finish();
  return file;
}

}  // namespace pt
