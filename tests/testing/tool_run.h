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

// The server's final status line ("server: robots ...") in a replay's captured output; empty
// when there is none.
inline std::string ServerStatusLine(const std::string& replay_output) {
  const size_t at = replay_output.find("server: robots");
  if (at == std::string::npos) return "";
  return replay_output.substr(at, replay_output.find('\n', at) - at);
}

// anchormap-eval of `map`'s relations error against `relations`, the poses completed by the
// odometry of the raw log `odometry`, its JSON to `output`; its exit code.
inline int EvalRelations(const std::string& map, const std::string& relations,
                         const std::string& odometry, const std::string& output) {
  return RunTool(
      "anchormap-eval",
      "--map " + map + " --relations " + relations + " --odometry " + odometry + " --json", output);
}

// The number after "key": in the eval's JSON, from `from` on (NaN when absent).
inline double JsonNumber(const std::string& json, const std::string& key, size_t from = 0) {
  const size_t at = json.find("\"" + key + "\":", from);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(json.c_str() + at + key.size() + 3, nullptr);
}

}  // namespace anchormap::testing
