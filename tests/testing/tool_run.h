#pragma once
// Tests that run the user's commands (import, replay, eval) on real data: a tool of this
// build and a number from anchormap-eval's JSON. Header-only: ANCHORMAP_BINARY_DIR is a
// test target's definition (cmake/AnchormapHelpers.cmake).

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <string>

namespace anchormap::testing {

// Runs build/bin/TOOL ARGUMENTS with stdout and stderr to `output`; its exit code (-1 when
// it did not exit).
inline int RunTool(const std::string& tool, const std::string& arguments,
                   const std::string& output) {
  const std::string command = std::string(ANCHORMAP_BINARY_DIR) + "/bin/" + tool + " " + arguments +
                              " >" + output + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The number after "key": in the eval's JSON, from `from` on (NaN when absent).
inline double JsonNumber(const std::string& json, const std::string& key, size_t from = 0) {
  const size_t at = json.find("\"" + key + "\":", from);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(json.c_str() + at + key.size() + 3, nullptr);
}

}  // namespace anchormap::testing
