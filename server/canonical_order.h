#pragma once
// The reorder stage in front of the graph (docs/ARCHITECTURE.md "Canonical input order").
// What the scan-matching sources accept depends on the graph's state when they look, so the
// server must build its graph in an order that depends on the input SET, not on the order
// in which the bus interleaved different robots' messages. This stage receives each
// trajectory's keyframes already gap-free and in sequence order (the delivery table) and
// the encounters as they come, and releases them in one canonical order - data time, then
// keyframes before encounters, then robot, trajectory id, sequence number - once every
// live trajectory's contiguous stream has passed that time (its watermark: the time of
// its last admitted keyframe). Two rules bound the wait, both on the caller's clock (wall
// time online, data time offline; nothing here reads a clock):
// - patience: a trajectory not heard from for patience_s (a parked robot, a finished or
//   crashed agent) stops holding the others (counted, logged by the caller); its data is
//   then ordered as it comes;
// - settle (online only): an input is released only settle_s after it arrived, so that a
//   robot whose first keyframes were lost on the radio is known before the others' inputs
//   of that time go out.
// Relayed encounters have a sequence of their own per observer trajectory: while one of
// those sequences has a gap, the missing encounters lie between the last contiguous one
// and the next received one in time, so inputs after the last contiguous one's time wait
// (for patience_s at most) for the resend. A keyframe reveals the same gap for an
// encounter with no later one: it carries the count its agent had relayed before it
// (ExpectEncounters), so the missing tail is known as soon as that keyframe arrives.
// An input that arrives after later inputs were released (a silent trajectory that speaks
// again, an encounter resent late) is released at once and counted as late: from then on
// the map may differ from one built from the same set in canonical order.

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/solver/keys.h"
#include "common/types/encounter.h"
#include "common/types/keyframe.h"
#include "common/util/status.h"

namespace anchormap {

struct CanonicalOrderOptions {
  // A trajectory silent this long (caller's clock) stops holding the others. Above the
  // delivery table's max_hold_s, so that a gap is bridged before its trajectory is given up.
  double patience_s = 15.0;
  // Online: an input waits at least this long (wall time) after its arrival. A keyframe
  // every 0.5 m comes every 1-2 s on a real robot, 4x faster in the loss test's replay.
  double settle_s = 2.0;
  // Offline (no clock set: data time), settle too: an input waits until inputs settle_s
  // newer have arrived (or the end). For a recording of a bus (anchormap-server --log on
  // what lcm-logger heard), whose first inputs need not come in canonical order: without
  // it the first keyframe to arrive goes out before the others' of that time are known,
  // takes solver id 0 and a first join found by scan matching is oriented the other way
  // than the live server's (daemon-intel.md: the loss test's "1 missing + 1 extra" link).
  bool settle_offline = false;
  // Inputs released into the graph per input or tick of the server (0: none there; the
  // online server releases from its timer, within a wall-time budget: a backlog released
  // from one message handler blocked its loop for 18 s in the loss test, and the resends it
  // did not read meanwhile were given up). The order, hence the map, does not depend on it.
  int release_per_call = 4;

  Status Validate() const {
    if (!(patience_s >= 0)) return Status::Error("order.patience_s must be >= 0");
    if (!(settle_s >= 0)) return Status::Error("order.settle_s must be >= 0");
    if (release_per_call < 0) return Status::Error("order.release_per_call must be >= 0");
    return Status::Ok();
  }
};

// One input on its way to the graph: a keyframe or an encounter.
struct OrderedInput {
  bool is_keyframe = true;
  Keyframe keyframe;
  Encounter encounter;
  int64_t utime() const { return is_keyframe ? keyframe.utime : encounter.utime; }
};

struct CanonicalOrderStats {
  int64_t released = 0;
  int64_t late = 0;       // released after an input that sorts after it
  int64_t silences = 0;   // times a trajectory stopped holding the others
  int64_t peak_held = 0;  // most inputs waiting at once
};

class CanonicalInputOrder {
 public:
  explicit CanonicalInputOrder(const CanonicalOrderOptions& options = {}) : options_(options) {}

  // A keyframe of trajectory `stream` (the delivery table's id), next in its sequence.
  void AddKeyframe(TrajectoryId stream, Keyframe keyframe, int64_t clock_utime);
  void AddEncounter(Encounter encounter, int64_t clock_utime);
  // Relayed encounters 0 .. count-1 of (observer, trajectory) exist (a keyframe's
  // encounters_relayed): the ones not arrived are a gap, which holds the inputs after the
  // last contiguous one's time as a gap between two arrived ones does.
  void ExpectEncounters(const std::string& observer, int64_t trajectory_id, int32_t count,
                        int64_t clock_utime);
  // `stream` was heard from (any keyframe received, also one waiting for a gap): it holds
  // the others from now on, for patience_s.
  void Heard(TrajectoryId stream, int64_t clock_utime);
  // A restarted server resumes at `clock_utime`: the patience of every trajectory still
  // holding, and of every encounter gap, counts from then at the earliest (the server's
  // downtime and journal replay are not the robots' silence), and so does the settle time
  // of every input waiting (what was lost while it was down is resent meanwhile).
  void ResumeAt(int64_t clock_utime);

  // The next input that may go to the graph at `now_utime`, if any (`settle`: apply
  // settle_s, online). Trajectories that fall silent at `now_utime` are appended to
  // `silenced` (may be null).
  std::optional<OrderedInput> Next(int64_t now_utime, bool settle,
                                   std::vector<TrajectoryId>* silenced = nullptr);
  // End of input: the next waiting input in canonical order, whatever holds it.
  std::optional<OrderedInput> NextAtEnd();

  size_t held() const;
  const CanonicalOrderStats& stats() const { return stats_; }

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  // The canonical sort key: (utime, encounter?, robot, trajectory id, seq, observed, arrival).
  using Key = std::tuple<int64_t, int, std::string, int64_t, int32_t, std::string, int64_t>;
  struct Entry {
    Key key;
    int64_t arrival_clock = 0;
    OrderedInput input;
  };
  // A relayed-encounter sequence (observer, observer trajectory id).
  struct EncounterStream {
    int32_t next_seq = 0;              // every seq below arrived
    int64_t last_utime = 0;            // time of seq next_seq - 1 (0 before any)
    std::map<int32_t, int64_t> above;  // seqs beyond a gap, with their times
    int64_t gap_since = 0;             // clock when the current gap opened
    int32_t expected = 0;              // a keyframe said every seq below this exists
    bool HasGap() const { return !above.empty() || expected > next_seq; }
  };
  struct Stream {
    std::deque<Entry> queue;
    bool started = false;
    int64_t watermark = 0;  // time of the last keyframe added (valid once started)
    int64_t last_heard = 0;
    bool silent = false;
  };

  // Where the smallest waiting entry is: a stream's front, or the encounters' first.
  struct Head {
    const Entry* entry = nullptr;
    Stream* stream = nullptr;  // null: the encounters
  };
  Head Smallest();
  OrderedInput Take(const Head& head);

  CanonicalOrderOptions options_;
  std::map<TrajectoryId, Stream> streams_;
  std::map<Key, Entry> encounters_;
  std::map<std::pair<std::string, int64_t>, EncounterStream> encounter_streams_;
  int64_t arrivals_ = 0;
  std::optional<Key> last_released_;
  CanonicalOrderStats stats_;
};

}  // namespace anchormap
