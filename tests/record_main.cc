// anchormap-test-record: records LCM channels into an LCM log for the system tests, in
// place of lcm-logger, whose 30-message queue per subscription dropped part of a server's
// final map on a loaded machine (tests/lcm_recorder.h).
//   --channels REGEX --output OUT.lcmlog [--lcm-url URL]
// Stops on SIGINT / SIGTERM after writing what LCM already received; then prints one line:
// "recorded N events (B bytes): CHANNEL=n ...; longest backlog K; kernel drops D".
// Exit 0 after a clean stop, 1 when LCM or the file failed, 2 for usage errors.

#include <csignal>
#include <iostream>
#include <string>

#include "common/util/options_loader.h"
#include "tests/lcm_recorder.h"

namespace anchormap {
namespace {

volatile std::sig_atomic_t stop_requested = 0;
void RequestStop(int) { stop_requested = 1; }

int Main(int argc, char** argv) {
  std::string channels, output, lcm_url;
  OptionsLoader loader("anchormap-test-record", "--channels REGEX --output OUT.lcmlog",
                       "Records the LCM channels matching REGEX into an LCM log until SIGINT "
                       "or SIGTERM, losing none between LCM's receive thread and the file.");
  loader.Add("channels", "channels", &channels,
             "LCM regular expression of the channels to record (as lcm-logger's -c)", true);
  loader.Add("output", "output", &output, "the LCM log to write (truncated)", true);
  loader.Add("lcm_url", "lcm-url", &lcm_url,
             "LCM URL (empty: $LCM_DEFAULT_URL or LCM's default); recv_buf_size=4194304 is "
             "added unless the URL sets one");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;

  // Installed before LCM starts its receive thread, which blocks every signal, so that the
  // signals reach this thread and interrupt its wait.
  struct sigaction action {};
  action.sa_handler = RequestStop;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);

  auto recorder = LcmRecorder::Open(lcm_url, channels, output);
  if (!recorder.ok()) {
    std::cerr << "anchormap-test-record: " << recorder.status().message() << "\n";
    return 1;
  }
  std::cout << "anchormap-test-record: recording '" << channels << "' into " << output << std::endl;
  const Status ran = (*recorder)->Run(&stop_requested);
  const RecorderCounts& counts = (*recorder)->counts();
  std::cout << "anchormap-test-record: recorded " << counts.events << " events (" << counts.bytes
            << " bytes):";
  for (const auto& [channel, events] : counts.events_per_channel) {
    std::cout << " " << channel << "=" << events;
  }
  std::cout << "; longest backlog " << counts.longest_backlog << "; kernel drops "
            << counts.kernel_drops << std::endl;
  if (!ran.ok()) {
    std::cerr << "anchormap-test-record: " << ran.message() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
