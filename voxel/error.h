// error.h: the one exception type thrown inside voxshadow; the CLI maps its kind to an exit status.
#ifndef VOXSHADOW_ERROR_H
#define VOXSHADOW_ERROR_H

#include <stdexcept>
#include <string>

namespace vs {

enum class ErrorKind {
  BadInput,  // the user's data or arguments are wrong (exit status 2)
  Runtime,   // the input was fine but the work failed: I/O, device, memory (exit status 1)
};

class Error : public std::runtime_error {
 public:
  Error(ErrorKind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const noexcept { return kind_; }

 private:
  ErrorKind kind_;
};

[[noreturn]] inline void throwBadInput(const std::string& message) { throw Error(ErrorKind::BadInput, message); }
[[noreturn]] inline void throwRuntime(const std::string& message) { throw Error(ErrorKind::Runtime, message); }

}  // namespace vs

#endif
