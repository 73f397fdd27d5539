#pragma once
// The interface of a pluggable encounter source. A source turns evidence that two
// trajectories met (a direct observation reported on the bus now; scan matching in a
// later issue) into encounter constraints between two keyframes, which MappingServer adds
// to the smoother. Sources are called on the server's single thread; a source that needs
// heavy work (scan matching) runs it on workers and hands results back in Poll().

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"
#include "common/types/constraint_kind.h"
#include "common/types/encounter.h"
#include "common/util/status.h"
#include "server/trajectory_table.h"
#include "server/trajectory_ties.h"

namespace anchormap {

class Smoother;

// An encounter tied to two keyframes: pose b measured in the frame of pose a. A loop closure
// (kind kLoopClosure) ties two keyframes of one trajectory and enters the smoother as a
// between factor; the other kinds join two trajectories.
struct EncounterConstraint {
  PoseKey a;
  PoseKey b;
  Pose2 measured_T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int64_t utime = 0;   // when it was observed
  std::string source;  // the source's name, for logs and statistics
  ConstraintKind kind = ConstraintKind::kDirectEncounter;
};

// What a source produced in one call.
struct EncounterSourceOutput {
  std::vector<EncounterConstraint> constraints;
  std::vector<Status> rejections;
};

// Read-only view of the graph handed to sources.
struct GraphView {
  const TrajectoryTable& table;
  const Smoother& smoother;  // current estimates (valid after the last Update())
  // The same smoother for covariance queries (memoised, hence not const); null when the
  // caller offers none (sources that need covariances then do nothing).
  Smoother* covariances = nullptr;
  // The constraints between trajectories in the graph (null when the caller keeps none: the
  // near search then adds no drift for the path since them).
  const TrajectoryTies* ties = nullptr;
};

class EncounterSource {
 public:
  virtual ~EncounterSource() = default;
  virtual std::string name() const = 0;

  // A direct encounter from the bus (sources that do not use them ignore it).
  virtual void OnEncounterMessage(const Encounter& /*encounter*/, const GraphView& /*graph*/,
                                  EncounterSourceOutput* /*out*/) {}
  // A keyframe entered the graph (a scan matcher searches for candidates here).
  virtual void OnKeyframeAdded(PoseKey /*key*/, const GraphView& /*graph*/,
                               EncounterSourceOutput* /*out*/) {}
  // Data time advanced to `now_utime` (called after every input): time-outs, results of
  // background work.
  virtual void Poll(int64_t /*now_utime*/, const GraphView& /*graph*/,
                    EncounterSourceOutput* /*out*/) {}
  // End of input: resolve what can be resolved, refuse the rest, but for what `out`'s
  // constraints may still resolve once in the graph (candidates kept for a pair they join).
  // MappingServer calls it again, once, after solving a join it made: a source that kept
  // something looks at it then.
  virtual void Flush(const GraphView& /*graph*/, EncounterSourceOutput* /*out*/) {}
  // Items waiting inside the source (for the status line).
  virtual size_t pending() const { return 0; }
  // The source's own figures for the status line ("" for none).
  virtual std::string StatsLine() const { return ""; }
  // True when the source's decisions depend on the estimate (a scan matcher gates its
  // candidates on it). MappingServer defers solver updates during a journal replay only
  // when no source does: otherwise the replayed decisions could differ from the live ones.
  virtual bool ReadsEstimate() const { return true; }
};

}  // namespace anchormap
