#include "server/keyframe_fold.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Cholesky>

#include "common/geometry/angle.h"
#include "server/encounter_candidate.h"
#include "server/keyframe_fold_state.h"
#include "server/keyframe_submap.h"

namespace anchormap {

namespace {

// Positions move between index refreshes by at most what one update moves them; candidates
// are asked within the radius plus this, then measured exactly.
constexpr double kIndexSlackM = 0.5;
constexpr double kIndexCellM = 2.0;

// The information-weighted mean of the predicted and the matched offset (in PoseError's
// coordinates, the gate's), with the prediction's covariance: the two are not independent (the
// agent matched the same scan against a local map holding the node's), and the product of
// both informations made the chains overconfident (ACES split in three: 13 loop closures
// refused by the gate, R3's start 0.5 m off its revisit, 0.0445 m against 0.0404 with the
// prediction's covariance). nullopt when a covariance is not positive definite (a zero one
// would read as a borrowed node's identity: PoseAlias::folded).
std::optional<KeyframeFold> FusedFold(PoseKey node, const Pose2& predicted,
                                      const Eigen::Matrix3d& predicted_covariance,
                                      const Pose2& matched,
                                      const Eigen::Matrix3d& match_covariance) {
  const auto positive = [](const Eigen::Matrix3d& m) {
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (m + m.transpose()));
    return ldlt.info() == Eigen::Success && ldlt.isPositive() && ldlt.vectorD().minCoeff() > 0.0;
  };
  if (!positive(predicted_covariance) || !positive(match_covariance)) return std::nullopt;
  const Eigen::Matrix3d sum = predicted_covariance + match_covariance;
  const Eigen::Matrix3d gain =
      match_covariance * Eigen::LDLT<Eigen::Matrix3d>(0.5 * (sum + sum.transpose()))
                             .solve(Eigen::Matrix3d::Identity());
  const Eigen::Vector3d step = gain * PoseError(predicted, matched);
  return KeyframeFold{
      node,
      Pose2(matched.x() + step.x(), matched.y() + step.y(), WrapAngle(matched.theta() + step.z())),
      0.5 * (predicted_covariance + predicted_covariance.transpose())};
}

}  // namespace

Status ReducedGraphOptions::Validate() const {
  if (!(radius_m > 0 && radius_m <= 10)) {
    return Status::Error("reduced_graph.radius_m (--reduced-graph-radius-m) must be in (0, 10]");
  }
  if (!(angle_deg > 0 && angle_deg <= 180)) {
    return Status::Error("reduced_graph.angle_deg (--reduced-graph-angle-deg) must be in (0, 180]");
  }
  if (!(min_score >= 0 && min_score < 1) || !(min_overlap >= 0 && min_overlap <= 1)) {
    return Status::Error("reduced_graph: min score in [0, 1), min overlap in [0, 1]");
  }
  if (!(gate_chi2 > 0)) return Status::Error("reduced_graph.gate_chi2 must be > 0");
  if (!(max_sigma_m > 0) || !(max_sigma_rad > 0)) {
    return Status::Error("reduced_graph.max_sigma_m and max_sigma_rad must be > 0");
  }
  if (!(max_range_m > 0)) return Status::Error("reduced_graph.max_range_m must be > 0");
  if (!(floor_sigma_m >= 0) || !(floor_sigma_rad >= 0)) {
    return Status::Error("reduced_graph covariance floors must be >= 0");
  }
  if (!(min_window_m > 0) || !(max_window_m >= min_window_m) || !(min_window_rad > 0) ||
      !(max_window_rad >= min_window_rad)) {
    return Status::Error("reduced_graph window: 0 < min <= max");
  }
  if (reference_cache < 1) return Status::Error("reduced_graph.reference_cache must be >= 1");
  if (Status s = reference.Validate(); !s.ok()) return s;
  return match.Validate();
}

KeyframeFolder::KeyframeFolder(const ReducedGraphOptions& options) : options_(options) {}

void KeyframeFolder::AddNode(PoseKey node, PoseKey keyframe, const Smoother& smoother) {
  const int32_t item = static_cast<int32_t>(nodes_.size());
  nodes_.push_back({node, keyframe});
  if (indexed_at_update_ >= 0) {
    index_.try_emplace(FrameOf(smoother, node.trajectory), kIndexCellM)
        .first->second.Add(item, smoother.GlobalPose(node).translation());
  }
}

void KeyframeFolder::RefreshIndex(const Smoother& smoother) {
  if (indexed_at_update_ == smoother.stats().updates) return;
  indexed_at_update_ = smoother.stats().updates;
  ++work_.index_refreshes;
  work_.indexed_nodes += static_cast<int64_t>(nodes_.size());
  index_.clear();
  // The frame's index looked up only when the frame changes from the previous node's (once the
  // team has joined, nearly all nodes share one frame; the map's lookup per node was a quarter
  // of the refresh at 100 robots).
  std::optional<TrajectoryFrame> last_frame;
  PositionIndex* index = nullptr;
  for (size_t i = 0; i < nodes_.size(); ++i) {
    const PoseKey node = nodes_[i].node;
    const TrajectoryFrame frame = FrameOf(smoother, node.trajectory);
    if (!last_frame || frame != *last_frame) {
      index = &index_.try_emplace(frame, kIndexCellM).first->second;
      last_frame = frame;
    }
    index->Add(static_cast<int32_t>(i), smoother.GlobalPose(node).translation());
  }
}

std::shared_ptr<const ScanReference> KeyframeFolder::NodeReference(const TrajectoryTable& table,
                                                                   PoseKey keyframe,
                                                                   TrajectoryId asking) {
  const std::pair<int64_t, int32_t> id{keyframe.trajectory.value(), keyframe.index};
  LastReference& last = last_reference_[asking];
  if (const auto it = references_.find(id); it != references_.end()) {
    // Least recently used goes first: a robot lingering at a node asks for it again and
    // again while others come and go.
    const auto used = std::find(reference_order_.begin(), reference_order_.end(), id);
    std::rotate(used, used + 1, reference_order_.end());
    ++work_.reference_hits;
    last = {id, it->second};
    return it->second;
  }
  if (last.reference != nullptr && last.id == id) {
    ++work_.reference_hits;
    ++work_.reference_own_hits;
    return last.reference;
  }
  const TrajectoryRecord* record = table.FindBySolverId(keyframe.trajectory);
  if (record == nullptr || keyframe.index >= record->num_keyframes()) return nullptr;
  PointCloud points = KeyframePoints(*record, keyframe.index, options_.max_range_m);
  if (points.empty()) return nullptr;
  ++work_.reference_builds;
  if (!ever_built_.insert(id).second) ++work_.reference_rebuilds;
  auto reference = std::make_shared<const ScanReference>(std::vector<PointCloud>{std::move(points)},
                                                         options_.reference);
  if (reference_order_.size() >= static_cast<size_t>(options_.reference_cache)) {
    references_.erase(reference_order_.front());
    reference_order_.erase(reference_order_.begin());
  }
  references_.emplace(id, reference);
  reference_order_.push_back(id);
  last = {id, reference};
  return reference;
}

std::optional<KeyframeFold> KeyframeFolder::Decide(PoseKey key, PoseKey previous,
                                                   const Pose2& T_previous_key,
                                                   const Eigen::Matrix3d& T_previous_key_covariance,
                                                   const TrajectoryTable& table,
                                                   Smoother* smoother) {
  ++stats_.examined;
  RefreshIndex(*smoother);
  const Pose2 predicted = Compose(smoother->GlobalPose(previous), T_previous_key);
  const auto frame = index_.find(FrameOf(*smoother, key.trajectory));
  if (frame == index_.end()) {
    ++stats_.no_candidate;
    return std::nullopt;
  }
  // The nearest node within the radius and angle (ties: the older node).
  const double max_angle = options_.angle_deg * kPi / 180.0;
  int32_t best = -1;
  double best_distance = 0.0;
  for (const int32_t item :
       frame->second.Near(predicted.translation(), options_.radius_m + kIndexSlackM)) {
    ++work_.near_nodes;
    const PoseKey node = nodes_[static_cast<size_t>(item)].node;
    if (FrameOf(*smoother, node.trajectory) != frame->first) continue;
    const Pose2 at = smoother->GlobalPose(node);
    const double distance = (at.translation() - predicted.translation()).norm();
    if (distance > options_.radius_m ||
        std::abs(WrapAngle(at.theta() - predicted.theta())) > max_angle) {
      continue;
    }
    ++work_.candidates;
    if (best < 0 || distance < best_distance || (distance == best_distance && item < best)) {
      best = item;
      best_distance = distance;
    }
  }
  if (best < 0) {
    ++stats_.no_candidate;
    return std::nullopt;
  }
  const PoseKey node = nodes_[static_cast<size_t>(best)].node;
  const PoseKey node_keyframe = nodes_[static_cast<size_t>(best)].keyframe;
  // The prediction of T_node_key and its covariance: the estimate's T_node_previous (joint
  // covariance from R) composed with the agent's constraint. When the predecessor is the
  // node's keyframe or folded onto the node, T_node_previous is its offset with the offset's
  // covariance (the identity, exactly, for the node's own keyframe): no solve through R,
  // which cost 7 % of a 100-robot replay with the option when every fold asked R.
  const PoseAlias* previous_alias = smoother->FindAlias(previous);
  const bool own_keyframe = node_keyframe == previous;
  const bool chained = own_keyframe || (previous_alias != nullptr && previous_alias->node == node);
  const std::optional<PredictedRelativePose> node_previous =
      own_keyframe ? std::optional<PredictedRelativePose>(
                         PredictedRelativePose{Pose2(), Eigen::Matrix3d::Zero(), false})
      : chained ? std::optional<PredictedRelativePose>(PredictedRelativePose{
                      previous_alias->T_node_key, previous_alias->covariance, false})
                : PredictRelativePose(smoother, node, previous);
  if (!chained) ++work_.solved_predictions;
  if (!node_previous) {
    ++stats_.unsolved;
    return std::nullopt;
  }
  Eigen::Matrix3d J_relative, J_step;
  const Pose2 guess = Compose(node_previous->T_a_b, T_previous_key, &J_relative, &J_step);
  const Eigen::Matrix3d predicted_covariance =
      J_relative * node_previous->covariance * J_relative.transpose() +
      J_step * T_previous_key_covariance * J_step.transpose();
  const TrajectoryRecord* record = table.FindBySolverId(key.trajectory);
  const std::shared_ptr<const ScanReference> reference =
      NodeReference(table, node_keyframe, key.trajectory);
  if (record == nullptr || reference == nullptr) {
    ++stats_.no_scan;
    return std::nullopt;
  }
  const PointCloud query = KeyframePoints(*record, key.index, options_.max_range_m);
  if (query.empty()) {
    ++stats_.no_scan;
    return std::nullopt;
  }
  LocalMatchOptions window;
  window.match = options_.match;
  window.match.covariance_min_score = options_.min_score;
  window.match.covariance_min_overlap = options_.min_overlap;
  if (options_.laplace_covariance) window.match.covariance_model = MatchCovariance::kLaplace;
  window.match.min_score = LatticeBarFor(options_.min_score, window.match.min_score);
  window.linear_window_m =
      std::clamp(3.0 * LargestSigma(predicted_covariance.topLeftCorner<2, 2>()),
                 options_.min_window_m, options_.max_window_m);
  window.angular_window_rad = std::clamp(3.0 * std::sqrt(std::max(0.0, predicted_covariance(2, 2))),
                                         options_.min_window_rad, options_.max_window_rad);
  ++work_.matches;
  work_.window_mm += std::lround(1e3 * window.linear_window_m);
  work_.window_mrad += std::lround(1e3 * window.angular_window_rad);
  // A chained prediction (the predecessor's own match and the agent's step: on 100 x 180 seed 2
  // sigma 3.8 cm and 0.017 rad at the median, the lattice's best pose within 1 cell and 15
  // angle steps of it in all 14,441 such matches) is within the refinement's reach: refined
  // from there, without the lattice search (a third of the fold's time). The lattice searches
  // the window when that refinement is weak or leaves the window.
  std::optional<MatchResult> match;
  if (chained && options_.refine_chained_from_guess) {
    match = RefineFromGuess(*reference, query, guess, window.match);
    const bool kept =
        match && match->score >= options_.min_score && match->overlap >= options_.min_overlap &&
        (match->pose.translation() - guess.translation()).norm() <= window.linear_window_m &&
        std::abs(WrapAngle(match->pose.theta() - guess.theta())) <= window.angular_window_rad;
    if (kept) {
      ++work_.guess_refinements;
    } else {
      ++work_.guess_fallbacks;
      match.reset();
    }
  }
  if (!match) {
    match = MatchLocal(*reference, query, guess, window);
    if (match) work_.lattice_scores += match->search.scored_nodes;
  }
  if (!match || match->score < options_.min_score || match->overlap < options_.min_overlap) {
    ++stats_.weak_match;
    return std::nullopt;
  }
  if (!Localised(match->covariance, options_.max_sigma_m, options_.max_sigma_rad)) {
    ++stats_.degenerate;
    return std::nullopt;
  }
  const Eigen::Matrix3d covariance =
      WithCovarianceFloor(match->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
  if (Mahalanobis2(guess, match->pose, predicted_covariance + covariance) > options_.gate_chi2) {
    ++stats_.gate_rejected;
    return std::nullopt;
  }
  ++stats_.folded;
  // The prediction is the predecessor's own chain (the node is its keyframe, or the
  // predecessor folded onto it): the agent's constraint then enters no factor (both keys are
  // the one node), so it is a second measurement of the offset, fused with the match (the
  // mean; the covariance stays the prediction's: FusedFold). With the match's floored
  // covariance alone (doubled in the factors through the fold), a fresh path, where every
  // other keyframe folds onto its predecessor, lost its odometry's precision: on ACES split in
  // two, R1[50] -> R1[170]'s heading sigma 0.011 -> 0.047 rad, and a wrong first join passed
  // the pairwise test (chi-square 21.9 -> 0.64; docs/ARCHITECTURE.md, aces26).
  if (chained) {
    if (std::optional<KeyframeFold> fused =
            FusedFold(node, guess, predicted_covariance, match->pose, covariance)) {
      return fused;
    }
  }
  return KeyframeFold{node, match->pose, covariance};
}

std::string KeyframeFolder::StatsLine() const {
  return "reduced graph: nodes " + std::to_string(nodes_.size()) + " folded " +
         std::to_string(stats_.folded) + " of " + std::to_string(stats_.examined) +
         " (no candidate " + std::to_string(stats_.no_candidate) + ", unsolved " +
         std::to_string(stats_.unsolved) + ", no scan " + std::to_string(stats_.no_scan) +
         ", weak " + std::to_string(stats_.weak_match) + ", gate " +
         std::to_string(stats_.gate_rejected) + ", degenerate " +
         std::to_string(stats_.degenerate) + ")";
}

std::string KeyframeFoldWork::Summary() const {
  return "fold work: index_refreshes " + std::to_string(index_refreshes) + " indexed_nodes " +
         std::to_string(indexed_nodes) + " near_nodes " + std::to_string(near_nodes) +
         " candidates " + std::to_string(candidates) + " solved_predictions " +
         std::to_string(solved_predictions) + " reference_builds " +
         std::to_string(reference_builds) + " reference_rebuilds " +
         std::to_string(reference_rebuilds) + " reference_hits " + std::to_string(reference_hits) +
         " reference_own_hits " + std::to_string(reference_own_hits) + " matches " +
         std::to_string(matches) + " window_mm " + std::to_string(window_mm) + " window_mrad " +
         std::to_string(window_mrad) + " lattice_scores " + std::to_string(lattice_scores) +
         " guess_refinements " + std::to_string(guess_refinements) + " guess_fallbacks " +
         std::to_string(guess_fallbacks);
}

KeyframeFolderState KeyframeFolder::ExportState() const {
  KeyframeFolderState s;
  for (const Node& n : nodes_) s.nodes.push_back({n.node, n.keyframe});
  for (const auto& [frame, index] : index_) s.index.emplace_back(frame, index.Entries());
  s.indexed_at_update = indexed_at_update_;
  s.stats = stats_;
  return s;
}

void KeyframeFolder::ImportState(const KeyframeFolderState& s) {
  nodes_.clear();
  for (const KeyframeFolderState::Node& n : s.nodes) nodes_.push_back({n.node, n.keyframe});
  // Added again in Entries order: each cell holds its items in the same order.
  index_.clear();
  for (const auto& [frame, entries] : s.index) {
    PositionIndex& index = index_.try_emplace(frame, kIndexCellM).first->second;
    for (const auto& [item, position] : entries) index.Add(item, position);
  }
  indexed_at_update_ = s.indexed_at_update;
  references_.clear();
  reference_order_.clear();
  last_reference_.clear();
  stats_ = s.stats;
}

}  // namespace anchormap
