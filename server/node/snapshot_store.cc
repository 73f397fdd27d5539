#include "server/node/snapshot_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace anchormap {
namespace {

constexpr char kPrefix[] = "snapshot-";
constexpr char kSuffix[] = ".bin";

Status IoError(const std::string& what, const std::string& path) {
  return Status::Error(ErrorCode::kIoError, what + " " + path + ": " + std::strerror(errno));
}

// Writes all of `bytes` to `fd`, retrying short writes.
bool WriteAll(int fd, const uint8_t* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

// The journal events a snapshot file name covers, or -1 when it is not one.
int64_t EventsOf(const std::string& name) {
  const size_t prefix = sizeof(kPrefix) - 1;
  const size_t suffix = sizeof(kSuffix) - 1;
  if (name.size() <= prefix + suffix || name.compare(0, prefix, kPrefix) != 0 ||
      name.compare(name.size() - suffix, suffix, kSuffix) != 0) {
    return -1;
  }
  const std::string digits = name.substr(prefix, name.size() - prefix - suffix);
  if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
      digits.size() > 18) {
    return -1;
  }
  return std::stoll(digits);
}

}  // namespace

Status WriteSnapshotFile(const std::string& dir, int64_t journal_events,
                         const std::vector<uint8_t>& bytes, int keep) {
  char name[64];
  std::snprintf(name, sizeof(name), "%s%012lld%s", kPrefix, static_cast<long long>(journal_events),
                kSuffix);
  const std::string temp = dir + "/snapshot.tmp";
  const std::string final_path = dir + "/" + name;
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return IoError("cannot create", temp);
  if (!WriteAll(fd, bytes.data(), bytes.size()) || ::fsync(fd) != 0) {
    const Status error = IoError("cannot write", temp);
    ::close(fd);
    ::unlink(temp.c_str());
    return error;
  }
  if (::close(fd) != 0) return IoError("cannot close", temp);
  if (::rename(temp.c_str(), final_path.c_str()) != 0) return IoError("cannot rename", temp);
  // The rename itself is durable once the directory is synced.
  const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd < 0) return IoError("cannot open", dir);
  const bool synced = ::fsync(dir_fd) == 0;
  ::close(dir_fd);
  if (!synced) return IoError("cannot sync", dir);
  const std::vector<std::string> all = ListSnapshotFiles(dir);
  for (size_t i = static_cast<size_t>(std::max(keep, 1)); i < all.size(); ++i) {
    std::error_code ignored;  // a file left behind is harmless (the newest is read first)
    std::filesystem::remove(all[i], ignored);
  }
  return Status::Ok();
}

std::vector<std::string> ListSnapshotFiles(const std::string& dir) {
  std::vector<std::pair<int64_t, std::string>> found;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(dir, error)) {
    const int64_t events = EventsOf(entry.path().filename().string());
    if (events >= 0) found.emplace_back(events, entry.path().string());
  }
  std::sort(found.rbegin(), found.rend());
  std::vector<std::string> paths;
  for (auto& [events, path] : found) paths.push_back(std::move(path));
  return paths;
}

Result<std::vector<uint8_t>> ReadSnapshotFile(const std::string& path) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return IoError("cannot open", path);
  std::vector<uint8_t> bytes;
  uint8_t buffer[1 << 16];
  size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), file)) > 0) {
    bytes.insert(bytes.end(), buffer, buffer + n);
  }
  const bool failed = std::ferror(file) != 0;
  std::fclose(file);
  if (failed) return IoError("cannot read", path);
  return bytes;
}

}  // namespace anchormap
