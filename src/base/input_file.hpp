// Input files (scenes, textures) are opened only when they are regular files: a FIFO, a device or a folder given
// as one is refused at once, with what it is, instead of blocking on it or reading it forever.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace pt {

// Which file a path names, whatever the name: its device and inode.
struct FileIdentity {
  dev_t device = 0;
  ino_t inode = 0;
  bool operator==(const FileIdentity&) const = default;
};

// The identity of an existing file (links followed), or nothing.
std::optional<FileIdentity> identity_of(const std::filesystem::path& path);

struct FileRead {
  FileIdentity identity;
  std::filesystem::path path;
};

// Every file InputFile::open has opened in this process (scenes, model files, textures): what outputs are checked
// never to overwrite.
std::vector<FileRead> files_read();

class InputFile {
 public:
  enum class Problem { kNone, kMissing, kFolder, kNotRegular, kCannotOpen };

  // Checks what `path` is before opening it, and again after (without blocking), in case it was replaced between.
  static InputFile open(const std::filesystem::path& path);

  InputFile(InputFile&& other) noexcept;
  InputFile& operator=(InputFile&& other) noexcept;
  ~InputFile();

  Problem problem() const { return problem_; }
  // For kNotRegular what the path is ("a FIFO (named pipe)", "a character device", ...); for kCannotOpen the
  // system's reason.
  const std::string& reason() const { return reason_; }
  int descriptor() const { return fd_; }
  // Gives up the descriptor (for instance to fdopen); the caller closes it.
  int release();
  // The whole content; false (errno set) on a read error.
  bool read_all(std::string& content);

 private:
  InputFile() = default;
  Problem problem_ = Problem::kNone;
  std::string reason_;
  int fd_ = -1;
};

}  // namespace pt
