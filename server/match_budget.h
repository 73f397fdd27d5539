#pragma once
// The matching work per second of data of one scan source (issue 12), bounded the way
// Cartographer samples its constraints, but spent by priority. Each source's keyframes, once
// solved, ask for their matches (a loop closure's candidates, a scan encounter's near
// searches); a match costs work units (a local match 1, a wide search more). The budget is
// a token bucket of units_per_s in data time, saving at most burst units, so the same input
// spends the same tokens (offline replays stay deterministic). The keyframes solved by one
// update are served together:
// - when the tokens cover every one of them at its largest cost (the real logs' one to three
//   robots, whose sources ask far less than the rate), all are served in arrival order, as
//   without a budget: the map is the same to the bit;
// - otherwise by priority: the trajectory that drove farthest since its last served keyframe
//   first (the drive no match has looked at yet: where a closure or an encounter brings the
//   most), while tokens last; a served keyframe pays what it actually submitted (the bucket
//   may go into debt by one keyframe's cost). The others are not served (a newer keyframe of
//   their trajectory sees as much of the place). A skipped keyframe adds skip_priority_m to
//   its trajectory's priority, so a trajectory that drives little (or not at all) is still
//   served: no trajectory starves.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/solver/keys.h"
#include "common/util/status.h"

namespace anchormap {

struct MatchBudgetOptions {
  double units_per_s = 0.0;  // per second of data, whole team (0: no bound)
  double burst = 60.0;       // most units saved up (also the start)
  // Priority (metres of drive) a trajectory gains per keyframe not served.
  double skip_priority_m = 0.5;

  // `prefix`: the flags' prefix in the message (e.g. "loop.budget").
  Status Validate(const std::string& prefix) const;
};

// A keyframe asking for its matches, with the drive (metres of odometry) of its trajectory
// from its first keyframe to it.
struct BudgetRequest {
  PoseKey key;
  double driven_m = 0.0;
};

class MatchBudget {
 public:
  explicit MatchBudget(const MatchBudgetOptions& options = {})
      : options_(options), tokens_(options.burst) {}

  bool bounded() const { return options_.units_per_s > 0; }
  // Data time advanced to now_utime (never goes back): tokens accrue.
  void Advance(int64_t now_utime);
  // Serves `requests` (in arrival order), each costing at most `max_units` (see the top):
  // `serve(key)` runs a keyframe's matches and returns the units it spent. Returns the keys
  // not served, in arrival order.
  std::vector<PoseKey> Serve(const std::vector<BudgetRequest>& requests, double max_units,
                             const std::function<double(PoseKey)>& serve);
  // Units spent outside Serve (the tests set the tokens with it; the sources charge nothing
  // else: a pair's catch-up is not charged): the keyframes that come next pay for them.
  void Spend(double units);

  double tokens() const { return tokens_; }
  double spent() const { return spent_; }
  int64_t skipped() const { return skipped_; }  // keyframes not served

  // The budget as plain values (snapshots).
  struct Ledger {
    double driven_m = 0.0;  // the trajectory's drive at its last served keyframe
    int64_t skips = 0;      // keyframes not served since
  };
  struct State {
    double tokens = 0.0;
    std::optional<int64_t> last_utime;
    std::map<TrajectoryId, Ledger> ledgers;
    double spent = 0.0;
    int64_t skipped = 0;
  };
  State ExportState() const { return {tokens_, last_utime_, ledgers_, spent_, skipped_}; }
  void ImportState(State s);

 private:
  double Priority(const BudgetRequest& request) const;
  void Served(const BudgetRequest& request, double units);

  MatchBudgetOptions options_;
  double tokens_;
  std::optional<int64_t> last_utime_;
  std::map<TrajectoryId, Ledger> ledgers_;
  double spent_ = 0.0;
  int64_t skipped_ = 0;
};

}  // namespace anchormap
