// anchormap-test-log-events: the events per channel of an LCM log, one "CHANNEL COUNT" line
// each in name order, then "total COUNT" (tests/record_test.sh counts what each recorder kept).
//   --log FILE.lcmlog
// Exit 0, 1 when the log cannot be read or holds corrupt stretches, 2 for usage errors.

#include <cstdint>
#include <iostream>
#include <map>
#include <string>

#include "common/bus/lcm_log.h"
#include "common/util/options_loader.h"

namespace anchormap {
namespace {

int Main(int argc, char** argv) {
  std::string path;
  OptionsLoader loader("anchormap-test-log-events", "--log FILE.lcmlog",
                       "Counts an LCM log's events per channel.");
  loader.Add("log", "log", &path, "the LCM log to read", true);
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  LcmLogReader reader;
  if (Status opened = reader.Open(path); !opened.ok()) {
    std::cerr << "anchormap-test-log-events: " << opened.message() << "\n";
    return 1;
  }
  std::map<std::string, int64_t> per_channel;
  int64_t total = 0;
  while (auto event = reader.Next()) {
    ++per_channel[event->channel];
    ++total;
  }
  for (const auto& [channel, events] : per_channel) std::cout << channel << " " << events << "\n";
  std::cout << "total " << total << "\n";
  for (const std::string& problem : reader.problems()) {
    std::cerr << "anchormap-test-log-events: " << problem << "\n";
  }
  return reader.problems().empty() ? 0 : 1;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
