#include "agent/spill_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace anchormap {
namespace {

Status IoError(const std::string& what) {
  return Status::Error(ErrorCode::kIoError, what + ": " + std::strerror(errno));
}

}  // namespace

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::unique_ptr<SpillFile>> SpillFile::Create(const std::string& dir) {
  std::string path = (std::filesystem::path(dir) / "anchormap-outbox.XXXXXX").string();
  const int fd = ::mkostemp(path.data(), O_CLOEXEC);
  if (fd < 0) return IoError("cannot create an outbox spill file in '" + dir + "'");
  if (::unlink(path.c_str()) != 0) {
    const Status error = IoError("cannot unlink " + path);
    ::close(fd);
    return error;
  }
  return std::unique_ptr<SpillFile>(new SpillFile(fd));
}

Result<int64_t> SpillFile::Append(const std::vector<uint8_t>& bytes) {
  const int64_t offset = size_;
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done,
                               static_cast<off_t>(offset + static_cast<int64_t>(done)));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return IoError("outbox spill write");
    done += static_cast<size_t>(n);
  }
  size_ += static_cast<int64_t>(bytes.size());
  return offset;
}

Result<std::vector<uint8_t>> SpillFile::Read(int64_t offset, size_t size) const {
  if (offset < 0 || offset + static_cast<int64_t>(size) > size_) {
    return Status::Error(ErrorCode::kInvalidArgument, "outbox spill read beyond the file");
  }
  std::vector<uint8_t> bytes(size);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, size - done,
                              static_cast<off_t>(offset + static_cast<int64_t>(done)));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return IoError("outbox spill read");
    done += static_cast<size_t>(n);
  }
  return bytes;
}

Status SpillFile::Clear() {
  if (::ftruncate(fd_, 0) != 0) return IoError("outbox spill truncate");
  size_ = 0;
  return Status::Ok();
}

}  // namespace anchormap
