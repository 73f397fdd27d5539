#pragma once
// The whole contents of a file, byte for byte, for tests that compare outputs or search
// a tool's text; "" when it cannot be read (the assertion on the contents then fails).

#include <fstream>
#include <iterator>
#include <string>

namespace anchormap::testing {

inline std::string FileContents(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace anchormap::testing
