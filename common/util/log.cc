#include "common/util/log.h"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <utility>

namespace anchormap {
namespace {

struct LogState {
  LogLevel min_level = LogLevel::kInfo;
  std::string component = "anchormap";
  LogSink sink;
};

LogState& State() {
  static LogState state;
  return state;
}

std::string WallClockText() {
  using std::chrono::system_clock;
  const auto now = system_clock::now();
  const std::time_t seconds = system_clock::to_time_t(now);
  const auto millis =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[32];
  const size_t length = std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%S", &utc);
  char millis_text[8];
  std::snprintf(millis_text, sizeof(millis_text), ".%03d", static_cast<int>(millis));
  return std::string(text, length) + millis_text;
}

}  // namespace

const char* ToString(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarning:
      return "warning";
    case LogLevel::kError:
      return "error";
  }
  return "?";
}

bool ParseLogLevel(const std::string& text, LogLevel* level) {
  if (text == "debug") {
    *level = LogLevel::kDebug;
  } else if (text == "info") {
    *level = LogLevel::kInfo;
  } else if (text == "warning" || text == "warn") {
    *level = LogLevel::kWarning;
  } else if (text == "error") {
    *level = LogLevel::kError;
  } else {
    return false;
  }
  return true;
}

void SetMinLogLevel(LogLevel level) { State().min_level = level; }
LogLevel MinLogLevel() { return State().min_level; }
void SetLogComponent(const std::string& component) { State().component = component; }
void SetLogSink(LogSink sink) { State().sink = std::move(sink); }

void Log(LogLevel level, const std::string& message) {
  LogState& state = State();
  if (level < state.min_level) return;
  static const char kLetters[] = {'D', 'I', 'W', 'E'};
  const std::string line = WallClockText() + " " + kLetters[static_cast<int>(level)] + " [" +
                           state.component + "] " + message;
  if (state.sink) {
    state.sink(level, line);
    return;
  }
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

bool OncePerKindLog::Log(LogLevel level, const std::string& kind, const std::string& message) {
  const int64_t seen = ++counts_[kind];
  if (seen != 1) return false;
  anchormap::Log(level, message + " (logged once for '" + kind + "'; later ones are counted)");
  return true;
}

int64_t OncePerKindLog::count(const std::string& kind) const {
  const auto it = counts_.find(kind);
  return it == counts_.end() ? 0 : it->second;
}

bool EveryNLog::Log(LogLevel level, const std::string& message) {
  const int64_t seen = count_++;
  if (seen % n_ != 0) return false;
  anchormap::Log(level, message + " [" + std::to_string(count_) + " so far]");
  return true;
}

}  // namespace anchormap
