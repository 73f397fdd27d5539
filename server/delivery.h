#pragma once
// The server's side of reliable delivery (docs/ARCHITECTURE.md, "A keyframe's path"),
// with no bus: which sequence numbers of a stream arrived (SeqWindow, for relayed
// encounters; keyframes are tracked by TrajectoryTable), and when a trajectory may be
// asked again for what it misses (ResendTracker). MappingServer builds the resend
// requests and acknowledgements from them; ServerNode encodes and publishes them.

#include <algorithm>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/types/trajectory_name.h"
#include "common/util/status.h"

namespace anchormap {

struct DeliveryOptions {
  // A trajectory that misses sequence numbers is asked for them at most this often
  // (caller's clock: wall time online). A little above the bus round trip.
  double resend_period_s = 0.3;

  Status Validate() const {
    if (!(resend_period_s >= 0)) return Status::Error("delivery.resend_period_s must be >= 0");
    return Status::Ok();
  }
};

// The sequence numbers of one stream that arrived: every seq below next() and the ones
// in above(). Memory: the numbers above the first gap.
class SeqWindow {
 public:
  // False when `seq` arrived before (a duplicate). Precondition: seq >= 0.
  bool Insert(int32_t seq);
  bool Contains(int32_t seq) const { return seq < next_ || above_.count(seq) > 0; }
  // Every number below `count` exists (a keyframe said so: Keyframe::encounters_relayed),
  // arrived or not: the ones that did not are missing even when nothing after them came.
  void Expect(int32_t count) { expected_ = std::max(expected_, count); }
  int32_t next() const { return next_; }
  // The missing numbers below the highest arrived or expected one, as inclusive ranges.
  std::vector<std::pair<int32_t, int32_t>> Missing() const;
  // Gives the missing numbers up (they will never come: e.g. acknowledged by a server
  // that was restarted); returns how many. Later arrivals of them are duplicates.
  int32_t GiveUpMissing();

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  int32_t next_ = 0;
  std::set<int32_t> above_;
  int32_t expected_ = 0;  // the highest count a keyframe gave (Expect)
};

// Rate limit of resend requests per trajectory (robot, agent trajectory id).
class ResendTracker {
 public:
  explicit ResendTracker(const DeliveryOptions& options = {}) : options_(options) {}
  // True (and remembered) when a request to this trajectory may go out at `now_utime`.
  bool Due(const TrajectoryName& trajectory, int64_t now_utime);

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  DeliveryOptions options_;
  std::map<TrajectoryName, int64_t> last_request_utime_;
};

}  // namespace anchormap
