// Writes the seed corpus: fuzz-seeds DIR -> DIR/<target>/seed-<n> (tests/fuzz/corpus).
#include <filesystem>
#include <fstream>
#include <iostream>

#include "tests/fuzz/fuzz_samples.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: fuzz-seeds CORPUS_DIR\n";
    return 2;
  }
  for (const auto& [target, inputs] : anchormap::fuzz::SeedInputs()) {
    const std::filesystem::path dir = std::filesystem::path(argv[1]) / target;
    std::filesystem::create_directories(dir);
    for (size_t i = 0; i < inputs.size(); ++i) {
      std::ofstream out(dir / ("seed-" + std::to_string(i)), std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(inputs[i].data()),
                static_cast<std::streamsize>(inputs[i].size()));
      if (!out) {
        std::cerr << "fuzz-seeds: cannot write " << dir << "\n";
        return 1;
      }
    }
  }
  return 0;
}
