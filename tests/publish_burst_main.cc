// anchormap-test-publish-burst: publishes COUNT messages of BYTES bytes on CHANNEL as fast as
// LCM sends them (a server's final map is such a burst), for tests/record_test.sh. Message i
// starts with i (4 bytes, big-endian); the rest is filler.
//   --channel NAME [--count 200] [--bytes 10000] [--lcm-url URL]
// Exit 0 when every publish succeeded, 1 otherwise, 2 for usage errors.

#include <lcm/lcm.h>

#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "common/util/options_loader.h"

namespace anchormap {
namespace {

int Main(int argc, char** argv) {
  std::string channel, lcm_url;
  int count = 200;
  int bytes = 10000;
  OptionsLoader loader("anchormap-test-publish-burst", "--channel NAME",
                       "Publishes COUNT numbered messages of BYTES bytes at once.");
  loader.Add("channel", "channel", &channel, "the channel to publish on", true);
  loader.Add("count", "count", &count, "messages to publish");
  loader.Add("bytes", "bytes", &bytes, "bytes per message (at least 4)");
  loader.Add("lcm_url", "lcm-url", &lcm_url, "LCM URL (empty: $LCM_DEFAULT_URL or LCM's default)");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  if (count < 1 || bytes < 4) {
    return loader.UsageError(Status::Error("--count must be >= 1 and --bytes >= 4"));
  }
  lcm_t* lcm = lcm_create(lcm_url.empty() ? nullptr : lcm_url.c_str());
  if (!lcm) {
    std::cerr << "anchormap-test-publish-burst: cannot open LCM at '" << lcm_url << "'\n";
    return 1;
  }
  std::vector<uint8_t> message(static_cast<size_t>(bytes), 0x5a);
  int failures = 0;
  for (int i = 0; i < count; ++i) {
    const auto index = static_cast<uint32_t>(i);
    for (int b = 0; b < 4; ++b) message[static_cast<size_t>(b)] = (index >> (24 - 8 * b)) & 0xff;
    if (lcm_publish(lcm, channel.c_str(), message.data(), static_cast<unsigned>(bytes)) != 0) {
      ++failures;
    }
  }
  lcm_destroy(lcm);
  std::cout << "anchormap-test-publish-burst: published " << count - failures << " of " << count
            << " messages of " << bytes << " bytes on " << channel << std::endl;
  return failures == 0 ? 0 : 1;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
