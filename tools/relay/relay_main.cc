// anchormap-relay: a lossy radio between two LCM URLs, for tests. Messages on the
// --channels of --from are published on --to, each dropped with probability --drop,
// duplicated with --duplicate, or held back (reordered) with --reorder until 1-3 later
// messages have passed (or 50 ms without traffic); messages on the --back-channels of --to
// are published on --from (with the same impairments when --impair-back). A seeded
// generator decides, so the decisions are reproducible for a given message order. Counts
// go to stdout at exit (SIGINT / SIGTERM).

#include <chrono>
#include <cstdio>
#include <deque>
#include <iostream>
#include <map>
#include <random>

#include "common/bus/lcm_loop.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"

namespace anchormap {
namespace {

struct RelayOptions {
  std::string from;
  std::string to;
  std::string channels = "ANCHORMAP_KEYFRAMES|ANCHORMAP_ENCOUNTERS";
  std::string back_channels = "ANCHORMAP_ACKS|ANCHORMAP_RESEND_REQUESTS";
  double drop = 0.3;
  double duplicate = 0.05;
  double reorder = 0.1;
  bool impair_back = false;
  int64_t seed = 1;
};

struct Counts {
  int64_t received = 0, forwarded = 0, dropped = 0, duplicated = 0, reordered = 0;
};

class Link {
 public:
  Link(const RelayOptions& o, LcmLoop* to, bool impaired, std::mt19937_64* rng)
      : options_(o), to_(to), impaired_(impaired), rng_(rng) {}

  void OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
    ++counts_.received;
    std::vector<uint8_t> bytes(data, data + size);
    if (!impaired_) return Send(channel, bytes);
    const double u = std::uniform_real_distribution<double>(0.0, 1.0)(*rng_);
    if (u < options_.drop) {
      ++counts_.dropped;
      return ReleaseHeld(false);
    }
    if (u < options_.drop + options_.reorder) {
      ++counts_.reordered;
      const int after = 1 + static_cast<int>((*rng_)() % 3);
      held_.push_back({channel, std::move(bytes), after});
      return;
    }
    Send(channel, bytes);
    if (u < options_.drop + options_.reorder + options_.duplicate) {
      ++counts_.duplicated;
      Send(channel, bytes);
    }
    ReleaseHeld(false);
  }
  // Held messages go out after their count of later messages, or all on a quiet tick.
  void ReleaseHeld(bool all) {
    for (auto it = held_.begin(); it != held_.end();) {
      if (all || --it->after <= 0) {
        Send(it->channel, it->bytes);
        it = held_.erase(it);
      } else {
        ++it;
      }
    }
  }
  const Counts& counts() const { return counts_; }
  int64_t last_activity = 0;

 private:
  struct Held {
    std::string channel;
    std::vector<uint8_t> bytes;
    int after;
  };
  void Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    ++counts_.forwarded;
    if (!to_->Publish(channel, bytes).ok()) LogWarning("publish on " + channel + " failed");
  }
  RelayOptions options_;
  LcmLoop* to_;
  bool impaired_;
  std::mt19937_64* rng_;
  std::deque<Held> held_;
  Counts counts_;
};

void Print(const char* name, const Counts& c) {
  std::printf(
      "anchormap-relay %s: received %lld forwarded %lld dropped %lld duplicated %lld "
      "reordered %lld\n",
      name, static_cast<long long>(c.received), static_cast<long long>(c.forwarded),
      static_cast<long long>(c.dropped), static_cast<long long>(c.duplicated),
      static_cast<long long>(c.reordered));
  std::fflush(stdout);
}

int Main(int argc, char** argv) {
  RelayOptions o;
  OptionsLoader loader("anchormap-relay", "--from URL --to URL [options]",
                       "Forwards LCM channels between two URLs with seeded loss, duplication and\n"
                       "reordering (a lossy radio for tests).");
  loader.Add("from", "from", &o.from, "LCM URL of the senders (the agents' side)", true);
  loader.Add("to", "to", &o.to, "LCM URL of the receivers (the server's side)", true);
  loader.Add("channels", "channels", &o.channels, "channels forwarded from -> to (LCM regex)");
  loader.Add("back_channels", "back-channels", &o.back_channels,
             "channels forwarded to -> from (LCM regex)");
  loader.Add("drop", "drop", &o.drop, "probability that a message is dropped");
  loader.Add("duplicate", "duplicate", &o.duplicate, "probability that a message is sent twice");
  loader.Add("reorder", "reorder", &o.reorder,
             "probability that a message is held back behind 1-3 later ones");
  loader.Add("impair_back", "impair-back", &o.impair_back, "impair the back direction too");
  loader.Add("seed", "seed", &o.seed, "random seed");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  if (!(o.drop >= 0 && o.duplicate >= 0 && o.reorder >= 0 &&
        o.drop + o.duplicate + o.reorder <= 1)) {
    return loader.UsageError(
        Status::Error("--drop, --duplicate, --reorder must be >= 0 with sum <= 1"));
  }
  SetLogComponent("anchormap-relay");
  Result<std::unique_ptr<LcmLoop>> from_created = LcmLoop::Create(o.from);
  Result<std::unique_ptr<LcmLoop>> to_created = LcmLoop::Create(o.to);
  for (const auto* created : {&from_created, &to_created}) {
    if (!created->ok()) {
      LogError(created->status().message());
      return 1;
    }
  }
  std::unique_ptr<LcmLoop> from = std::move(*from_created);
  std::unique_ptr<LcmLoop> to = std::move(*to_created);
  std::mt19937_64 rng(static_cast<uint64_t>(o.seed));
  Link forward(o, to.get(), /*impaired=*/true, &rng);
  Link back(o, from.get(), o.impair_back, &rng);
  int64_t ticks = 0, forward_seen = 0, back_seen = 0;
  Status s = from->Subscribe(
      o.channels,
      [&](const std::string& c, const uint8_t* d, size_t n) { forward.OnMessage(c, d, n); }, 10000);
  if (s.ok()) {
    s = to->Subscribe(
        o.back_channels,
        [&](const std::string& c, const uint8_t* d, size_t n) { back.OnMessage(c, d, n); }, 10000);
  }
  if (!s.ok()) {
    LogError(s.message());
    return 1;
  }
  // One thread: `from` runs the loop; `to` is drained every millisecond; held messages
  // go out after 50 ms without traffic on their link.
  from->Every(std::chrono::milliseconds(1), [&] {
    to->HandlePending();
    if (++ticks % 50 == 0) {
      if (forward.counts().received == forward_seen) forward.ReleaseHeld(true);
      if (back.counts().received == back_seen) back.ReleaseHeld(true);
      forward_seen = forward.counts().received;
      back_seen = back.counts().received;
    }
  });
  from->StopOnSignals();
  LogInfo("relaying '" + o.channels + "' " + o.from + " -> " + o.to + " and '" + o.back_channels +
          "' back");
  from->Run();
  forward.ReleaseHeld(true);
  back.ReleaseHeld(true);
  Print("forward", forward.counts());
  Print("back", back.counts());
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
