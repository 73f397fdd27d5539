#pragma once
// Where the agent's outbox puts what does not fit its memory bound (issue 13: a server away
// for a long time must not cost keyframes): one scratch file, written at its end, read back
// by offset. The file is created in a folder and unlinked at once, so it lives exactly as
// long as the agent (nothing is left behind by a crash; a restarted agent starts a new
// trajectory anyway). Truncated when nothing in it is needed any more.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

class SpillFile {
 public:
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  // A new, already unlinked file in `dir`; kIoError when it cannot be made there.
  static Result<std::unique_ptr<SpillFile>> Create(const std::string& dir);

  // Appends `bytes`; the offset to read them back at.
  Result<int64_t> Append(const std::vector<uint8_t>& bytes);
  // The `size` bytes written at `offset`.
  Result<std::vector<uint8_t>> Read(int64_t offset, size_t size) const;
  // Forgets everything written (the space goes back to the file system).
  Status Clear();

  int64_t size() const { return size_; }

 private:
  explicit SpillFile(int fd) : fd_(fd) {}
  int fd_ = -1;
  int64_t size_ = 0;
};

}  // namespace anchormap
