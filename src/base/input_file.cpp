// Opening input files: stat first, then open without blocking and fstat the descriptor, so that neither a special
// file nor one swapped in after the check is ever read.
#include "base/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <utility>

namespace pt {

namespace {

std::mutex files_read_mutex;
std::vector<FileRead> files_read_so_far;

const char* kind_of(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

}  // namespace

InputFile InputFile::open(const std::filesystem::path& path) {
  InputFile file;
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) {
    file.problem_ = (errno == ENOENT || errno == ENOTDIR) ? Problem::kMissing : Problem::kCannotOpen;
    file.reason_ = std::strerror(errno);
    return file;
  }
  if (S_ISDIR(status.st_mode)) {
    file.problem_ = Problem::kFolder;
    return file;
  }
  if (!S_ISREG(status.st_mode)) {
    file.problem_ = Problem::kNotRegular;
    file.reason_ = kind_of(status.st_mode);
    return file;
  }
  // O_NONBLOCK: should a FIFO have taken the file's place since the stat, opening it still returns at once.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    file.problem_ = errno == ENOENT ? Problem::kMissing : Problem::kCannotOpen;
    file.reason_ = std::strerror(errno);
    return file;
  }
  if (::fstat(fd, &status) != 0 || !S_ISREG(status.st_mode)) {
    file.problem_ = S_ISDIR(status.st_mode) ? Problem::kFolder : Problem::kNotRegular;
    file.reason_ = kind_of(status.st_mode);
    ::close(fd);
    return file;
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  file.fd_ = fd;
  const std::lock_guard lock(files_read_mutex);
  files_read_so_far.push_back({FileIdentity{status.st_dev, status.st_ino}, path});
  return file;
}

std::optional<FileIdentity> identity_of(const std::filesystem::path& path) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) return std::nullopt;
  return FileIdentity{status.st_dev, status.st_ino};
}

std::vector<FileRead> files_read() {
  const std::lock_guard lock(files_read_mutex);
  return files_read_so_far;
}

InputFile::InputFile(InputFile&& other) noexcept : problem_(other.problem_), reason_(std::move(other.reason_)), fd_(std::exchange(other.fd_, -1)) {}

InputFile& InputFile::operator=(InputFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    problem_ = other.problem_;
    reason_ = std::move(other.reason_);
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

int InputFile::release() { return std::exchange(fd_, -1); }

bool InputFile::read_all(std::string& content) {
  content.clear();
  struct stat status {};
  // The size known in advance, and one byte more for the read that finds the end: one allocation and no growth
  // copies (which would double the peak for large scenes).
  if (::fstat(fd_, &status) == 0 && status.st_size > 0) content.resize(static_cast<std::size_t>(status.st_size) + 1);
  std::size_t used = 0;
  for (;;) {
    if (used == content.size()) content.resize(content.size() + 65536);
    const ssize_t got = ::read(fd_, content.data() + used, content.size() - used);
    if (got < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (got == 0) break;
    used += static_cast<std::size_t>(got);
  }
  content.resize(used);
  return true;
}

}  // namespace pt
