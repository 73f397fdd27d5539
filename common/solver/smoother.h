#pragma once
// The incremental smoother: iSAM (Kaess et al., T-RO 2008) over several robot
// trajectories joined by anchor nodes (Kim et al., ICRA 2010). docs/METHOD.md sections 4-6.
//
// Usage: AddPose / AddBetween / AddEncounter queue variables and measurements; Update()
// folds them into the square-root information matrix R by Givens rotations (or runs a
// batch step) and solves. Estimates and covariances are read between updates.
// Single-threaded: callers serialise access (the server runs it on its event loop).

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/factor.h"
#include "common/solver/keys.h"
#include "common/solver/pose_aliases.h"
#include "common/solver/smoother_options.h"
#include "common/solver/sparse_r.h"
#include "common/util/status.h"

namespace anchormap {

// What one Update() did.
struct UpdateResult {
  Status status = Status::Ok();  // numerical trouble (e.g. an unconstrained variable) lands here
  int64_t update = 0;            // update number, 1, 2, ...
  bool batch_step = false;       // true when this update relinearised and reordered
  int iterations = 0;            // nonlinear iterations of the batch step (0 if incremental)
  int factors_added = 0;         // measurements folded into R for the first time
  int anchors_created = 0;
  int groups_merged = 0;         // encounters that joined two anchored groups
  int rows_backsubstituted = 0;  // block rows recomputed by back-substitution
  int relinearized = 0;          // variables relinearised by a partial step (0 if none)
  double seconds = 0.0;
};

// Cumulative counters, for benchmarks and the server's status line.
struct SmootherStats {
  int64_t updates = 0;
  int64_t batch_steps = 0;
  int64_t batch_steps_on_clock = 0;
  int64_t batch_steps_on_fill = 0;
  int64_t batch_steps_on_merge = 0;
  int64_t batch_steps_on_drift = 0;  // relinearize_threshold exceeded
  int64_t failed_batch_steps = 0;    // undone (ordering or factorisation failed)
  // Partial relinearisations (relinearize_threshold with partial_relinearization): the
  // drifted variables relinearised and only the rows of R depending on them re-eliminated.
  int64_t partial_relinearizations = 0;
  int64_t relinearized_variables = 0;  // summed over partial steps
  int64_t rows_reeliminated = 0;       // block rows of R re-eliminated, summed
  // Of those, the rows marked before the elimination-tree closure (S, the variables
  // sharing a factor with S, newest poses and anchors), and the rows from the first of
  // them to the end of R (what a column-ordered re-elimination would redo), summed.
  int64_t rows_before_closure = 0;
  int64_t rows_in_tails = 0;
  int64_t partial_merges = 0;    // group merges done by a partial step (also counted
                                 // in partial_relinearizations)
  double partial_seconds = 0.0;  // time spent in partial steps
  int64_t batch_iterations = 0;  // summed over batch steps
  int64_t iterations_to_convergence =
      0;                             // batch iterations until the step fell below convergence_step
  int64_t givens_block_rows = 0;     // block rows of R met by Givens eliminations
  int64_t givens_block_columns = 0;  // block columns they spanned (the elimination work)
  int64_t rows_backsubstituted = 0;
  // correction_tolerance: correction steps taken, updates whose correction did not
  // converge, and the time spent (gradient evaluations and triangular solves).
  int64_t correction_steps = 0;
  int64_t correction_stalls = 0;
  int64_t correction_skips = 0;  // updates whose new factors agreed with the estimate
  double correction_seconds = 0.0;
  int64_t variables = 0;
  int64_t factors = 0;
  int64_t nnz_r = 0;                 // scalar non-zeros of R (upper triangle)
  double batch_seconds = 0.0;        // time spent in batch steps
  double incremental_seconds = 0.0;  // time spent in incremental updates
};

// Work counters of the correction's gradient passes (not in SmootherState: a restored
// smoother counts from zero).
struct CorrectionWork {
  int64_t gradient_passes = 0;
  int64_t factors_linearized = 0;  // by those passes; the others were cached
};

struct SmootherState;  // smoother_state.h

class Smoother {
 public:
  explicit Smoother(const SmootherOptions& options = {});
  ~Smoother();
  Smoother(Smoother&&) noexcept;
  Smoother& operator=(Smoother&&) noexcept;

  const SmootherOptions& options() const;

  // Adds pose `key` with an initial guess in its trajectory's local frame. Index 0 starts
  // a new trajectory, whose local frame gets a gauge prior at that pose; later indices
  // must follow an existing pose of the trajectory (any order of indices is allowed, but
  // each key only once).
  Status AddPose(PoseKey key, const Pose2& initial_T_local_pose);

  // A measurement of pose `to` in the frame of pose `from`, both of one trajectory
  // (odometry, or a loop closure). Covariance: symmetric positive definite, (x, y, theta).
  Status AddBetween(PoseKey from, PoseKey to, const Pose2& measured_T_from_to,
                    const Eigen::Matrix3d& covariance);

  // An encounter: pose b measured in the frame of pose a, from two different trajectories
  // (direct or indirect). In the relative formulation this creates anchors at the first
  // encounter of a trajectory and merges anchor groups (dropping one gauge prior).
  Status AddEncounter(PoseKey a, PoseKey b, const Pose2& measured_T_a_b,
                      const Eigen::Matrix3d& covariance);

  // The reduced pose graph's fold (pose_aliases.h): `key` (new, of an existing trajectory)
  // gets no variable; it is `node` (a pose variable, of its trajectory or, once both are
  // anchored in one group, of another) composed with T_node_key. Pose and covariance queries
  // on it answer node (+) offset (the offset's own covariance left out: it enters the
  // measurements mapped through it); AddBetween / AddEncounter on it add the measurement
  // between the nodes (MapToNodes: a between factor when they share a trajectory, an
  // encounter otherwise, nothing when both keys fold onto one node).
  Status AddAlias(PoseKey key, PoseKey node, const Pose2& T_node_key,
                  const Eigen::Matrix3d& covariance);
  // The key of the next node borrowed from trajectory t (kBorrowedNodeIndexBase): AddPose it,
  // then AddAlias the keyframe onto it with the identity and a zero covariance.
  PoseKey NextBorrowedNode(TrajectoryId t) const;
  // nullptr when `key` is no alias.
  const PoseAlias* FindAlias(PoseKey key) const { return aliases_.Find(key); }
  // True when `key` folded onto a node made for another keyframe (PoseAlias::folded).
  bool IsFolded(PoseKey key) const {
    const PoseAlias* alias = aliases_.Find(key);
    return alias != nullptr && alias->folded();
  }
  int64_t NumAliases() const { return static_cast<int64_t>(aliases_.size()); }
  // Measurements between two keys folded onto one node (added as nothing).
  int64_t measurements_inside_nodes() const { return measurements_inside_nodes_; }

  // Folds everything added since the last call into the solution. All or nothing: when a
  // batch step fails (result.status), the estimate and the pending measurements are as
  // they were before the call, and the next Update() tries again.
  UpdateResult Update();
  // Forces a batch step now (relinearise, reorder, refactor, iterate until the largest step
  // component is below `convergence_step`; <= 0 means options().convergence_step).
  UpdateResult BatchOptimize(double convergence_step = 0.0);

  // --- Estimates (valid after Update()) ---
  // Preconditions, checked (std::invalid_argument, a caller's bug): the pose/variable/
  // trajectory passed to FramePose, GlobalPose and Value exists (HasPose, HasVariable),
  // and a covariance is asked only of variables that are solved (HasCovariance).
  // A pose variable or an alias (AddAlias).
  bool HasPose(PoseKey key) const;
  // The trajectory's keys, variables and aliases (borrowed nodes are no keys of it).
  int NumPoses(TrajectoryId trajectory) const;
  std::vector<TrajectoryId> Trajectories() const;  // in order of creation
  // The pose in the frame the smoother keeps it in: its trajectory's local frame in the
  // relative formulation, the shared frame of its group in the global formulations.
  Pose2 FramePose(PoseKey key) const;
  // The pose in the global frame: Anchor (+) FramePose once anchored; FramePose before.
  Pose2 GlobalPose(PoseKey key) const;
  bool IsAnchored(TrajectoryId trajectory) const;
  // T_global_local of an anchored trajectory (relative formulation); nullopt otherwise.
  std::optional<Pose2> Anchor(TrajectoryId trajectory) const;
  // The trajectory whose gauge defines the frame this trajectory's group is expressed in.
  TrajectoryId GroupRoot(TrajectoryId trajectory) const;

  // --- Covariances (docs/METHOD.md section 6; from R, never a dense inverse) ---
  // True when `key` is a variable already solved for (in R): a variable whose measurements
  // do not determine it yet has no covariance.
  bool HasCovariance(const Key& key) const;
  // True when `key` is solved (HasCovariance) and no group change is pending
  // (GroupChangePending): its covariance in R then describes the graph's groups. Between
  // updates R holds the last update's graph; a pending merge already joined two groups
  // here, but R still holds them apart (each with its own gauge prior), so a covariance
  // across them read before Update() would describe a graph that no longer exists.
  bool IsSolved(const Key& key) const;
  // An anchor or a group merge added since the last Update(): trajectories' frames changed
  // and R does not know it yet.
  bool GroupChangePending() const;
  // Anything added since the last Update() (variables or factors not yet in R).
  bool HasPendingChanges() const;
  // Marginal 3x3 covariance of one variable, (x, y, theta) of the variable's own
  // coordinates. Memoised until the next Update().
  Eigen::Matrix3d MarginalCovariance(const Key& key);
  // Joint covariance of several variables, 3k x 3k, blocks in the order given.
  Eigen::MatrixXd JointCovariance(const std::vector<Key>& keys);
  // J Sigma J^T of a 3-row Jacobian J = [J_1 ... J_k] of the variables `keys` (e.g. a
  // relative pose's): one sparse solve, without the joint's blocks, so it costs what the
  // variables' paths to the bottom of R hold, not that corner's cube
  // (CovarianceProjection, covariances.h). The same query asked again before R changes is
  // answered from a memo, with the same bits.
  Eigen::Matrix3d ProjectedCovariance(const std::vector<Key>& keys,
                                      const std::vector<Eigen::Matrix3d>& jacobians);
  // The same solve, stopped once `enough` holds for the sum so far, a lower bound of the
  // result (CovarianceProjection::ComputeUntil): false and that bound when it stopped early,
  // true and ProjectedCovariance's bits otherwise.
  bool ProjectedCovarianceUntil(const std::vector<Key>& keys,
                                const std::vector<Eigen::Matrix3d>& jacobians,
                                const std::function<bool(const Eigen::Matrix3d&)>& enough,
                                Eigen::Matrix3d* covariance);
  // Each key's marginal covariance by the same solve (ProjectedCovariance(key, I)'s bits),
  // the keys' solves run side by side, reading each row of R once for all of them.
  std::vector<Eigen::Matrix3d> ProjectedMarginals(const std::vector<Key>& keys);
  // Several ProjectedCovariance queries, each with its bits (and its memo), their solves
  // run side by side (CovarianceProjection::ComputeSideBySide): R's rows read once for all.
  struct CovarianceQuery {
    std::vector<Key> keys;
    std::vector<Eigen::Matrix3d> jacobians;
  };
  std::vector<Eigen::Matrix3d> ProjectedCovariances(const std::vector<CovarianceQuery>& queries);

  // The current estimate of any variable (pose: local frame; anchor: T_global_local) or
  // alias (its FramePose).
  Pose2 Value(const Key& key) const;
  // True for variables only (an alias is none).
  bool HasVariable(const Key& key) const;
  // Every active factor (gauge priors included), for exports, journals and test oracles.
  std::vector<Factor> ActiveFactors() const;

  // Sum of squared whitened residuals of every factor at the current estimate.
  double Chi2() const;
  const SmootherStats& stats() const;
  CorrectionWork correction_work() const;
  // Each trajectory's poses in the global frame, in index order (convenience for outputs).
  std::vector<Pose2> GlobalTrajectory(TrajectoryId trajectory) const;

  // For tests (the per-update oracle): the linear system R delta = d held now.
  struct LinearSystem {
    std::vector<Key> keys;               // by elimination position
    std::vector<Pose2> linearization;    // theta, by position
    std::vector<RBlockRow> rows;         // R and d, by position
    std::vector<Eigen::Vector3d> delta;  // by position; the estimate is theta + delta
    std::vector<Factor> factors;         // the factors whose rows are in R
    // For each of them, the values (in FactorKeys order) its rows were linearised at:
    // J(x - theta) = J (at - theta) - e(at).
    std::vector<std::vector<Pose2>> linearized_at;
  };
  LinearSystem LinearSystemForTesting() const;

  // The incremental state (smoother_state.h), for snapshots. ImportState takes the state of a
  // smoother that was given the same Add* calls as this one, in the same order, and nothing
  // since (no Update()); it refuses (kInvalidArgument, nothing changed) a state that does not
  // fit this graph. The smoother then continues exactly as the exporting one would.
  SmootherState ExportState() const;
  Status ImportState(SmootherState state);

 private:
  class Impl;
  // The variables and Jacobians a key's FramePose depends on: itself, or an alias's node
  // (and the two anchors when the node is another trajectory's).
  std::vector<std::pair<Key, Eigen::Matrix3d>> Terms(const Key& key) const;
  // A query on keys that may be aliases as the same query on variables (each once).
  CovarianceQuery OnVariables(const std::vector<Key>& keys,
                              const std::vector<Eigen::Matrix3d>& jacobians) const;
  bool AnyAlias(const std::vector<Key>& keys) const;
  // A measurement mapped onto the nodes (MapToNodes): nothing inside one node, else a
  // between factor within a trajectory or an encounter across two.
  Status AddBetweenNodes(const NodeMeasurement& m);

  std::unique_ptr<Impl> impl_;
  PoseAliases aliases_;
  std::unordered_map<TrajectoryId, int32_t> borrowed_nodes_;  // per trajectory
  int64_t measurements_inside_nodes_ = 0;
};

}  // namespace anchormap
