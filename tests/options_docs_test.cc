// docs/DAEMONS.md's option tables are what the daemons print: a flag added, renamed or
// given a new default without the document fails here, so the document stays true.

#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <string>
#include "tests/testing/file_contents.h"

namespace anchormap {
namespace {

// stdout of `command`, or "" when it could not run.
std::string Output(const std::string& command) {
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  if (!pipe) return "";
  std::string out;
  char buffer[4096];
  size_t n = 0;
  while ((n = fread(buffer, 1, sizeof buffer, pipe.get())) > 0) out.append(buffer, n);
  return out;
}

// The text of "## <tool> options" up to the next "## " heading.
std::string Section(const std::string& document, const std::string& tool) {
  const std::string heading = "## " + tool + " options\n";
  const size_t start = document.find(heading);
  if (start == std::string::npos) return "";
  const size_t end = document.find("\n## ", start + heading.size());
  return document.substr(start, end == std::string::npos ? std::string::npos : end - start);
}

class OptionsDocsTest : public ::testing::TestWithParam<const char*> {};

TEST_P(OptionsDocsTest, DaemonsMdHoldsTheToolsOwnTable) {
  const std::string tool = GetParam();
  const std::string table =
      Output(std::string(ANCHORMAP_BINARY_DIR) + "/bin/" + tool + " --print-options-markdown");
  ASSERT_NE(table.find("| flag | config key | default | meaning |"), std::string::npos)
      << tool << " printed no table";
  const std::string section = Section(
      ::anchormap::testing::FileContents(std::string(ANCHORMAP_SOURCE_DIR) + "/docs/DAEMONS.md"),
      tool);
  ASSERT_FALSE(section.empty()) << "docs/DAEMONS.md has no '## " << tool << " options'";
  EXPECT_NE(section.find(table), std::string::npos)
      << "docs/DAEMONS.md's table for " << tool << " differs from `" << tool
      << " --print-options-markdown`; paste the tool's output into the document";
}

INSTANTIATE_TEST_SUITE_P(Daemons, OptionsDocsTest,
                         ::testing::Values("anchormap-agent", "anchormap-server",
                                           "anchormap-replay", "anchormap-viewer"),
                         [](const auto& info) {
                           std::string name = info.param;
                           for (char& c : name) {
                             if (c == '-') c = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace anchormap
