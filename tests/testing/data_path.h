#pragma once
// Where the public datasets are (../shared/data by default, or $ANCHORMAP_DATA_DIR).
// Tests that need them call ANCHORMAP_REQUIRE_DATA(path) and skip with a clear message
// when the file is absent.

#include <cstdlib>
#include <filesystem>
#include <string>

namespace anchormap::testing {

inline std::string DataDir() {
  if (const char* env = std::getenv("ANCHORMAP_DATA_DIR"); env && *env) return env;
#ifdef ANCHORMAP_DEFAULT_DATA_DIR
  return ANCHORMAP_DEFAULT_DATA_DIR;
#else
  return "../shared/data";
#endif
}

// Returns the full path of `relative` inside the data directory ("" if absent).
inline std::string DataFile(const std::string& relative) {
  const std::filesystem::path path = std::filesystem::path(DataDir()) / relative;
  return std::filesystem::exists(path) ? path.string() : std::string();
}

}  // namespace anchormap::testing

#define ANCHORMAP_REQUIRE_DATA(var, relative)                                               \
  const std::string var = ::anchormap::testing::DataFile(relative);                         \
  if (var.empty()) {                                                                        \
    GTEST_SKIP() << "data file '" << (relative) << "' not found in '"                       \
                 << ::anchormap::testing::DataDir()                                         \
                 << "' (set ANCHORMAP_DATA_DIR to the folder holding posegraph/, carmen/)"; \
  }
