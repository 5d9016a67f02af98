// The two kinds of error the program reports as one line and a non-zero exit: bad input, and a failing backend.
#pragma once

#include <stdexcept>

namespace pt {

// Bad input: the message names the file and the place in it. Thrown only by host code, never in kernels.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Errors of a backend (no device, out of memory, a failed launch): one clear line, never a crash.
class BackendError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pt
