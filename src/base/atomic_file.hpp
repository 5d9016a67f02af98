// The one way the program writes a file: to a temporary beside it, every write checked, synced, then renamed into place.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace pt {

// A file written to a hidden temporary in the target's folder and renamed over the target only once every write,
// the sync to disk and the close have succeeded. Whatever fails (a full disk, an I/O error, a folder where the file
// should go), the target is never replaced or truncated and the temporary is removed. Errors throw InputError with
// one line: "TARGET: cannot write WHAT: REASON", REASON being the operating system's.
//
// Writing happens in two steps so that several files can be published together (all or nothing): finish() puts
// the bytes on disk and closes the temporary; publish() renames it into place. A file destroyed before publish()
// removes its temporary.
// Where a write to `path` lands: the file its symbolic links lead to (a link is written through, not replaced),
// or `path` itself. A chain of more than 40 links is left as it is (the write then fails as the system says).
std::filesystem::path written_path(const std::filesystem::path& path);

class AtomicFile {
 public:
  // Creates the temporary. `what` names the content in messages ("the image", "the table").
  AtomicFile(std::filesystem::path target, std::string what);
  AtomicFile(AtomicFile&& other) noexcept;
  AtomicFile& operator=(AtomicFile&&) = delete;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  const std::filesystem::path& target() const { return target_; }

  void write(const void* data, std::size_t bytes);
  void write(const std::string& text) { write(text.data(), text.size()); }
  // The offset the next write goes to, and moving it (for formats that fill in a table after the data).
  std::uint64_t position() const { return position_; }
  void seek(std::uint64_t offset);

  // Writes what is buffered, syncs the file to disk and closes it.
  void finish();
  // finish() if not done yet, then renames the temporary over the target.
  void publish();

  // Throws the error of a failed step of this file. A writer whose callbacks cannot throw (OpenEXR's stream
  // destructors swallow exceptions) records the failure here, so publish() refuses the file all the same.
  [[noreturn]] void fail(const std::string& reason);

 private:
  void flush_buffer();
  void write_all(const char* data, std::size_t bytes);
  void remove_temporary() noexcept;

  std::filesystem::path target_, temporary_;
  std::string what_;
  int fd_ = -1;
  std::vector<char> buffer_;  // writes gathered into large ones: OpenEXR writes a few bytes at a time
  std::uint64_t position_ = 0;
  std::string failure_;  // the first error; non-empty: the file is never published
  bool published_ = false;
  int temporary_slot_ = -1;  // where remove_temporaries_now() finds the temporary
};

// Removes every temporary of the AtomicFiles alive now. Safe in a signal handler (it only calls unlink): an
// interrupt that ends the program at once leaves no temporary behind.
void remove_temporaries_now() noexcept;

// `content` written to an AtomicFile for `target` and finished: it takes its place when published.
AtomicFile write_file_unpublished(const std::filesystem::path& target, const std::string& what, const std::string& content);

// For tests of the failure paths: makes one step of the next file writes fail with the operating-system error
// `error` (e.g. ENOSPC), as a full disk or a failing device would. kWrite fails once `after_bytes` bytes have been
// written in this process since the call; the other steps fail at their first occurrence. kNone turns it off.
enum class FileStep { kNone, kCreate, kWrite, kSync, kClose, kRename };
void inject_file_failure(FileStep step, int error, std::uint64_t after_bytes = 0);

}  // namespace pt
