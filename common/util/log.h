#pragma once
// One-line logging with levels, plus the two rate limits daemons need: once per kind
// (a bad message of a given kind is logged the first time only; the rest are counted)
// and every N-th occurrence. Lines go to stderr (or a test sink) as
//   2024-05-01T12:00:00.123 W [server] message
// Single-threaded by design (one event loop per daemon); the sink swap is for tests.

#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>

namespace anchormap {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3 };

const char* ToString(LogLevel level);
// Parses "debug", "info", "warning" / "warn", "error" (case-sensitive, lower case).
bool ParseLogLevel(const std::string& text, LogLevel* level);

// Messages below this level are dropped. Default kInfo.
void SetMinLogLevel(LogLevel level);
LogLevel MinLogLevel();
// The component name printed in brackets (e.g. the program name). Default "anchormap".
void SetLogComponent(const std::string& component);

// Replaces where formatted lines go (nullptr restores stderr). For tests.
using LogSink = std::function<void(LogLevel level, const std::string& line)>;
void SetLogSink(LogSink sink);

// Writes one line (a trailing newline is added).
void Log(LogLevel level, const std::string& message);
inline void LogDebug(const std::string& m) { Log(LogLevel::kDebug, m); }
inline void LogInfo(const std::string& m) { Log(LogLevel::kInfo, m); }
inline void LogWarning(const std::string& m) { Log(LogLevel::kWarning, m); }
inline void LogError(const std::string& m) { Log(LogLevel::kError, m); }

// Logs a message the first time a given kind is seen; later calls for the same kind
// only count. Returns true when it logged.
class OncePerKindLog {
 public:
  bool Log(LogLevel level, const std::string& kind, const std::string& message);
  int64_t count(const std::string& kind) const;

 private:
  std::unordered_map<std::string, int64_t> counts_;
};

// Logs the 1st, (N+1)-th, (2N+1)-th ... call, with the number of calls so far.
class EveryNLog {
 public:
  explicit EveryNLog(int64_t n) : n_(n < 1 ? 1 : n) {}
  bool Log(LogLevel level, const std::string& message);
  int64_t count() const { return count_; }

 private:
  int64_t n_;
  int64_t count_ = 0;
};

}  // namespace anchormap
