#pragma once
// The reduced pose graph's fold (docs/ARCHITECTURE.md, "Bounding the graph by area"): a
// keyframe released in an already mapped place becomes an alias of an existing node (a
// keyframe that got a pose variable) instead of a new variable, so that the graph grows with
// the area, not with time. At a keyframe's release (canonical order: a replay folds the same
// way) its pose is predicted from its predecessor's estimate and the agent's constraint; the
// candidates are the nodes of its frame (its anchored group, or its own trajectory while
// unanchored) within a radius and angle of the prediction; the nearest is verified by one
// local match of the keyframe's scan against the node's, gated as loop closures gate theirs
// (score, overlap, chi-square against the prediction's covariance). Pass: the keyframe folds
// with the match as its offset. Fail or no candidate: it becomes a node, as without the option.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/scan_reference.h"
#include "common/solver/keys.h"
#include "common/solver/smoother.h"
#include "common/util/status.h"
#include "server/position_index.h"
#include "server/relative_pose.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct ReducedGraphOptions {
  bool enabled = false;
  // A node is a candidate when the predicted pose lies this close (position, heading).
  double radius_m = 1.0;
  double angle_deg = 30.0;
  // The verifying match's bars and gate: the loop closures' defaults (LoopClosureOptions).
  double min_score = 0.5;
  double min_overlap = 0.7;
  double gate_chi2 = 11.34;  // 3 dof, 99 %
  double max_range_m = 15.0;
  double floor_sigma_m = 0.02;
  double floor_sigma_rad = 0.005;
  // The verifying match's window: three sigmas of the predicted T_node_keyframe, within
  // these. The floors are a fifth and a quarter of the loop closures' (0.4 m, 0.2 rad): a
  // prediction from the keyframe's predecessor is tight (100 x 180 seed 2: sigma 3.8 cm and
  // 0.017 rad at the median, the lattice pose within 1 cell and 15 angle steps of it in all
  // 20,423 matches), so a third the angles and a fifth the cells hold the same lattice pose:
  // outputs byte-identical on seeds 1, 2, 3 and 5 (docs/ARCHITECTURE.md, cost28).
  double min_window_m = 0.1;
  double max_window_m = 2.0;
  double min_window_rad = 0.05;
  double max_window_rad = 0.6;
  // A fold needs a match localised in every direction, as a first join does
  // (ScanEncounterOptions::first_join_max_sigma_*): a corridor's match is free along it, and
  // the keyframe, published at node (+) match, lands where the match slid (Intel with the
  // option: 46 relations off by 0.3-1.7 m, mean error 0.0229 -> 0.034 m). Such a keyframe
  // becomes a node, tied by its odometry as without the option.
  double max_sigma_m = 0.1;
  double max_sigma_rad = 0.05;
  // Node references kept built (a revisited place matches against the same node again).
  // A single scan's reference is several MB: 256 doubled a 100-robot replay's memory
  // (0.85 -> 1.7 GB); 32 kept it at 0.86 GB with the same output. Besides these, each
  // trajectory keeps the reference it last matched against (KeyframeFolder::NodeReference).
  int reference_cache = 32;
  // Three max-grid levels (blocks up to 4 cells): the window is a few cells wide, and branch
  // and bound finds the same best lattice pose on any pyramid; the levels above were built
  // for every reference and read by no search (cost28).
  ScanReferenceOptions reference{0.05, 0.05, 0.5, 3};
  MatchOptions match;
  // The match's covariance by the Laplace approximation (MatchCovariance::kLaplace) instead of
  // the score distribution's 125 cost evaluations, half of the fold's match (foldcov26,
  // docs/ARCHITECTURE.md); degenerate directions still get the window prior, so the bar
  // above still refuses a corridor's sliding match.
  bool laplace_covariance = true;
  // A chained fold's match (the predecessor is the node's keyframe or folded onto the node) is
  // refined from the prediction without the lattice search (RefineFromGuess; cost28).
  bool refine_chained_from_guess = true;

  Status Validate() const;
};

// Where a keyframe folds: T_node_keyframe measured by the match, its covariance (floored).
struct KeyframeFold {
  PoseKey node;
  Pose2 T_node_keyframe;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};

struct KeyframeFoldStats {
  int64_t examined = 0;      // keyframes with a predecessor
  int64_t no_candidate = 0;  // no node within the radius and angle
  int64_t unsolved = 0;      // no covariance to gate with yet (new variables not in R)
  int64_t no_scan = 0;       // the keyframe's or the node's scan is empty
  int64_t weak_match = 0;    // no match, or under the score or overlap bar
  int64_t gate_rejected = 0;
  int64_t degenerate = 0;  // the match not localised in every direction (max_sigma_*)
  int64_t folded = 0;
};

// What the folds cost, counted for the status (not in snapshots: a restored folder starts
// at 0 with its reference cache empty).
struct KeyframeFoldWork {
  int64_t index_refreshes = 0;     // the nodes' positions indexed again (a solver update)
  int64_t indexed_nodes = 0;       // nodes indexed by those refreshes
  int64_t near_nodes = 0;          // nodes the index gave within the radius plus its slack
  int64_t candidates = 0;          // of those, within the radius and angle
  int64_t solved_predictions = 0;  // T_node_previous solved through R
  int64_t reference_builds = 0;    // node references built (the cache's misses)
  int64_t reference_rebuilds = 0;  // of those, of a node built before (evicted since)
  int64_t reference_hits = 0;
  int64_t reference_own_hits = 0;  // of those, the asking trajectory's last reference
  int64_t matches = 0;             // verifying matches run
  // Their search windows (sums: mm and mrad of the half-widths) and lattice work.
  int64_t window_mm = 0;
  int64_t window_mrad = 0;
  int64_t lattice_scores = 0;
  // Chained folds' matches refined from the prediction alone (RefineFromGuess), and those that
  // fell back to the lattice search (weak, or the refinement left the window).
  int64_t guess_refinements = 0;
  int64_t guess_fallbacks = 0;

  std::string Summary() const;
};

struct KeyframeFolderState;  // keyframe_fold_state.h

class KeyframeFolder {
 public:
  explicit KeyframeFolder(const ReducedGraphOptions& options);

  // A keyframe became a node (a pose variable of the smoother: its own key, or a node
  // borrowed from another trajectory, kBorrowedNodeIndexBase); its scan is the node's.
  void AddNode(PoseKey node, PoseKey keyframe, const Smoother& smoother);
  // Where keyframe `key` (admitted, its record in `table`) folds, predicted at
  // `previous` (+) T_previous_key; nullopt: it becomes a node.
  std::optional<KeyframeFold> Decide(PoseKey key, PoseKey previous, const Pose2& T_previous_key,
                                     const Eigen::Matrix3d& T_previous_key_covariance,
                                     const TrajectoryTable& table, Smoother* smoother);

  const KeyframeFoldStats& stats() const { return stats_; }
  const KeyframeFoldWork& work() const { return work_; }
  size_t num_nodes() const { return nodes_.size(); }
  std::string StatsLine() const;

  // Snapshots (keyframe_fold_state.h). ImportState replaces everything but the options and
  // leaves the reference cache empty (rebuilt on demand).
  KeyframeFolderState ExportState() const;
  void ImportState(const KeyframeFolderState& state);

 private:
  // The nodes' positions by frame, rebuilt once the estimate moved (a solver update).
  void RefreshIndex(const Smoother& smoother);
  // The reference of a node's scan (`keyframe`'s), for a fold of a keyframe of `asking`.
  std::shared_ptr<const ScanReference> NodeReference(const TrajectoryTable& table, PoseKey keyframe,
                                                     TrajectoryId asking);

  ReducedGraphOptions options_;
  struct Node {
    PoseKey node;
    PoseKey keyframe;  // whose scan verifies a fold onto it
  };
  std::vector<Node> nodes_;
  std::map<TrajectoryFrame, PositionIndex> index_;
  int64_t indexed_at_update_ = -1;
  std::map<std::pair<int64_t, int32_t>, std::shared_ptr<const ScanReference>> references_;
  std::vector<std::pair<int64_t, int32_t>> reference_order_;  // least recently used first
  std::set<std::pair<int64_t, int32_t>> ever_built_;          // KeyframeFoldWork's count
  // Per trajectory, the node reference its last fold's match used: a robot's next keyframe
  // usually asks for it again (a fresh path folds onto its own newest node), and among 100
  // robots the shared least-recently-used cache had evicted it by then.
  struct LastReference {
    std::pair<int64_t, int32_t> id;
    std::shared_ptr<const ScanReference> reference;
  };
  std::map<TrajectoryId, LastReference> last_reference_;
  KeyframeFoldStats stats_;
  KeyframeFoldWork work_;
};

}  // namespace anchormap
