#pragma once
// A folder of scratch files for the running test. ctest runs every test of a binary as its
// own process, in parallel: a fixed file name under /tmp is shared by tests that run at the
// same time (and by two builds tested at once), so each test process gets its own folder.

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace anchormap::testing {

// <temp>/anchormap-<pid>-<suite>.<test>/, created empty on first use in each test.
inline std::filesystem::path ScratchDir() {
  const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test_name =
      test ? std::string(test->test_suite_name()) + "." + test->name() : std::string("global");
  std::string folder = "anchormap-" + std::to_string(::getpid()) + "-" + test_name;
  for (char& c : folder) {
    if (c == '/') c = '_';  // parameterised test names contain slashes
  }
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / folder;
  // Removed at exit when every test passed; kept for a look when one failed.
  struct Folder {
    std::filesystem::path path;
    void RemoveIfAllPassed() {
      std::error_code ignored;
      if (!path.empty() && ::testing::UnitTest::GetInstance()->Passed()) {
        std::filesystem::remove_all(path, ignored);
      }
    }
    ~Folder() { RemoveIfAllPassed(); }
  };
  static Folder created;
  if (created.path != dir) {
    created.RemoveIfAllPassed();  // the previous test's, when the binary runs several
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    created.path = dir;
  }
  return dir;
}

inline std::string ScratchPath(const std::string& name) { return (ScratchDir() / name).string(); }

}  // namespace anchormap::testing
