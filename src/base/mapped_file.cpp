// Read-only mappings of input files, with their passed pages dropped from resident memory.
#include "base/mapped_file.hpp"

#include <signal.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>

namespace pt {

namespace {

// Dropping pages costs a system call: done once this many bytes have been passed.
constexpr std::size_t kReleaseStep = std::size_t{8} << 20;

// The file whose mapping a SIGBUS came from: a file shrunk by another program while mapped. One mapping at a time
// installs the handler (scene files are read one at a time); the name is kept in a fixed buffer for the handler.
char shrunk_file_message[1024];
std::atomic<int> mappings{0};
struct sigaction previous_sigbus {};

extern "C" void on_sigbus(int) {
  const ssize_t ignored = ::write(STDERR_FILENO, shrunk_file_message, std::strlen(shrunk_file_message));
  (void)ignored;
  ::_exit(1);
}

}  // namespace

std::unique_ptr<MappedFile> MappedFile::map(int descriptor, std::size_t size, const std::string& name) {
  if (size == 0) return nullptr;
  void* data = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, descriptor, 0);
  if (data == MAP_FAILED) return nullptr;
  ::madvise(data, size, MADV_SEQUENTIAL);
  if (mappings.fetch_add(1) == 0) {
    const std::string message = name + ": the file shrank while it was being read\n";
    const std::size_t length = std::min(message.size(), sizeof shrunk_file_message - 1);
    std::memcpy(shrunk_file_message, message.data(), length);
    shrunk_file_message[length] = '\0';
    struct sigaction action {};
    action.sa_handler = on_sigbus;
    sigemptyset(&action.sa_mask);
    ::sigaction(SIGBUS, &action, &previous_sigbus);
  }
  return std::unique_ptr<MappedFile>(new MappedFile(static_cast<const char*>(data), size));
}

MappedFile::~MappedFile() {
  ::munmap(const_cast<char*>(data_), size_);
  if (mappings.fetch_sub(1) == 1) ::sigaction(SIGBUS, &previous_sigbus, nullptr);
}

void MappedFile::passed(std::size_t offset) {
  static const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  offset = std::min(offset, size_);
  const std::size_t end = offset / page * page;  // whole pages only: the mapping starts on a page
  // A reader that starts over (the objects read after the outline) drops pages again from where it now is.
  if (end < released_) released_ = end;
  if (offset < released_ + kReleaseStep) return;
  ::madvise(const_cast<char*>(data_) + released_, end - released_, MADV_DONTNEED);
  released_ = end;
}

}  // namespace pt
