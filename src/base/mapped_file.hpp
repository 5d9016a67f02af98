// A large input file read through a read-only mapping instead of a copy: the text is the page cache's, and the
// pages a reader has passed leave the process's resident memory, so reading a file of hundreds of megabytes does not
// add its size to the process's peak.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

namespace pt {

class MappedFile {
 public:
  // Maps `size` bytes of the open regular file `descriptor` (named `name` in messages); nullptr where the system
  // cannot map it (an empty file, a file system without mappings), to be read the ordinary way instead. Should the
  // file shrink while it is mapped, reading past its new end stops the process with one line naming the file and
  // exit status 1 (the mapping's pages beyond the end cannot be read).
  static std::unique_ptr<MappedFile> map(int descriptor, std::size_t size, const std::string& name);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  std::string_view text() const { return {data_, size_}; }
  // The text before `offset` will be read again only for a message: its pages are dropped from resident memory
  // (read again from the page cache or the file if they are). Cheap to call often: it acts every few megabytes. A
  // reader may start over from an earlier place: pages are then dropped again from there on.
  void passed(std::size_t offset);

 private:
  MappedFile(const char* data, std::size_t size) : data_(data), size_(size) {}
  const char* data_;
  std::size_t size_;
  std::size_t released_ = 0;  // where the pages still resident in this sweep begin
};

}  // namespace pt
