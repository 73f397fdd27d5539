#include "server/loop_closures.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "common/scan_matching/lattice_search.h"
#include "common/scan_matching/point_cloud.h"
#include "common/util/log.h"
#include "server/held_matches.h"
#include "server/keyframe_submap.h"
#include "server/relative_pose.h"

namespace anchormap {

Status LoopClosureOptions::Validate() const {
  if (min_index_gap < 1) return Status::Error("loop.min_index_gap must be >= 1");
  if (!(max_distance_m > 0)) return Status::Error("loop.max_distance_m must be > 0");
  if (!(candidate_chi2 > 0) || !(gate_chi2 > 0))
    return Status::Error("loop chi2 gates must be > 0");
  if (max_candidates < 0) return Status::Error("loop.max_candidates must be >= 0");
  if (!(saturation_m >= 0)) return Status::Error("loop.saturation_m must be >= 0");
  if (cooldown_keyframes < 0) return Status::Error("loop.cooldown_keyframes must be >= 0");
  if (submap_half_width < 0) return Status::Error("loop.submap_half_width must be >= 0");
  if (!(max_range_m > 0)) return Status::Error("loop.max_range_m must be > 0");
  if (!(min_window_m > 0) || !(max_window_m >= min_window_m))
    return Status::Error("loop window: 0 < min_window_m <= max_window_m");
  if (!(min_window_rad > 0) || !(max_window_rad >= min_window_rad))
    return Status::Error("loop window: 0 < min_window_rad <= max_window_rad");
  if (!(floor_sigma_m >= 0) || !(floor_sigma_rad >= 0))
    return Status::Error("loop covariance floors must be >= 0");
  if (max_waiting < 1) return Status::Error("loop.max_waiting must be >= 1");
  if (!(wide_sigmas > 0) || !(wide_max_window_m > 0) || !(wide_max_window_rad > 0) ||
      wide_max_window_rad > kPi || wide_max_window_m > 100.0) {
    return Status::Error("loop wide window: sigmas > 0, 0 < max m <= 100, 0 < max rad <= pi");
  }
  if (!(drift_per_m >= 0) || !(drift_rad_per_m >= 0) || wide_quiet_keyframes < 0) {
    return Status::Error("loop drift model: per m >= 0, rad per m >= 0, quiet >= 0");
  }
  if (wide_submap_max_keyframes < 1 || !(wide_submap_spacing_m >= 0) ||
      !(wide_submap_spacing_rad >= 0)) {
    return Status::Error("loop wide submap by place: max keyframes >= 1, spacings >= 0");
  }
  if (wide_submap_half_width < 0 || wide_every_keyframes < 1 || wide_pair_min_gap < 1 ||
      wide_pair_max_gap < wide_pair_min_gap || wide_max_kept < 1) {
    return Status::Error(
        "loop wide: submap half width >= 0, every >= 1, 1 <= pair min gap <= max gap, kept >= 1");
  }
  if (!(wide_min_score >= 0 && wide_min_score < 1) || !(wide_min_overlap >= 0) ||
      !(wide_pair_chi2 > 0)) {
    return Status::Error("loop wide: min score in [0, 1), min overlap >= 0, pair chi2 > 0");
  }
  if (!(wide_weak_min_overlap >= 0) || !(wide_pair_min_separation_m >= 0) ||
      !(refine_look_ahead_m >= 0) || !(refine_choice_radius_m >= 0) ||
      !(wide_weak_partner_max_sigma_m > 0)) {
    return Status::Error(
        "loop wide: weak min overlap >= 0, pair min separation >= 0, refine look-ahead and "
        "choice radius >= 0, weak partner max sigma > 0");
  }
  if (Status s = reference.Validate(); !s.ok()) return s;
  if (Status s = submap_cache.Validate(); !s.ok()) return s;
  if (Status s = budget.Validate("loop.budget"); !s.ok()) return s;
  if (!(budget_wide_units >= 0) || !std::isfinite(budget_wide_units)) {
    return Status::Error("loop.budget_wide_units must be finite and >= 0");
  }
  if (!(budget_wide_nodes_per_unit >= 0) || !std::isfinite(budget_wide_nodes_per_unit)) {
    return Status::Error("loop.budget_wide_nodes_per_unit must be finite and >= 0");
  }
  return match.Validate();
}

namespace {

// Squared Mahalanobis distance of the offset t from the disc of radius r around 0.
double DistanceFromDisc2(const Eigen::Vector2d& t, const Eigen::Matrix2d& covariance, double r) {
  const double norm = t.norm();
  if (norm <= r) return 0.0;
  const Eigen::Vector2d outside = t - t * (r / norm);
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(covariance);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 0.0) return 1e30;
  return outside.dot(ldlt.solve(outside));
}

double LargestSigma(const Eigen::Matrix2d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

// The path the estimate drives between two keyframes of one trajectory (steps between
// keyframes without an estimate count 0).
double EstimatedPath(const Smoother& smoother, TrajectoryId trajectory, int32_t a, int32_t b) {
  double path = 0.0;
  for (int32_t i = std::min(a, b); i < std::max(a, b); ++i) {
    const PoseKey from{trajectory, i}, to{trajectory, i + 1};
    if (!smoother.HasPose(from) || !smoother.HasPose(to)) continue;
    path += (smoother.FramePose(from).translation() - smoother.FramePose(to).translation()).norm();
  }
  return path;
}

// SearchWindowAndFinish, except that a window holding no pose above the bar still gives a
// result: score 0 (see FoundPose) with the search's stats, which the budget charges by.
std::optional<MatchResult> WideSearch(const ScanReference& reference, const PointCloud& query,
                                      const SearchWindow& window, const MatchOptions& options) {
  if (reference.empty() || query.empty()) return std::nullopt;
  const DiscretisedQuery discretised(query, window, reference.geometry());
  LatticeSearchStats stats;
  const std::optional<LatticePose> best =
      BranchAndBound(reference.pyramid(), discretised, window, options.min_score, &stats);
  MatchResult result;  // score 0: no pose
  if (best) result = FinishMatch(reference, query, window, *best, options);
  result.search = stats;
  return result;
}

// The prefilter's slack: 3 sigma of the keyframe's marginal position, twice. The marginal
// by one projected solve (J = I), not the block recursion (MarginalCovariance): the
// recursion needs every pair of the dense corner of R below the keyframe, the solve only
// the rows on its path (8.4 % of the samples late in a 20-robot run went to the recursion
// for this alone). The same value up to round-off; it only widens a radius.
double PrefilterSlack(Smoother* smoother, PoseKey key) {
  const Eigen::Matrix3d marginal =
      smoother->ProjectedCovariance({Key(key)}, {Eigen::Matrix3d::Identity()});
  return 6.0 * LargestSigma(marginal.topLeftCorner<2, 2>());
}

// Whether a wide search's result holds a pose (WideSearch: its score is above the bar, > 0).
bool FoundPose(const MatchResult& wide) { return wide.score > 0.0; }

}  // namespace

void LoopClosures::ChargeWideBySize(const LatticeSearchStats& search) {
  if (!budget_.bounded() || options_.budget_wide_nodes_per_unit <= 0) return;
  const double units =
      static_cast<double>(search.scored_nodes) / options_.budget_wide_nodes_per_unit;
  if (units <= options_.budget_wide_units) return;
  // The submit charged budget_wide_units already.
  const double beyond = units - options_.budget_wide_units;
  units_by_size_ += beyond;
  budget_.Spend(beyond);
}

void LoopClosures::OnKeyframeAdded(PoseKey key, const GraphView& graph,
                                   EncounterSourceOutput* /*out*/) {
  // A keyframe folded onto a node (the reduced graph) was matched against that node's scan
  // already, and its odometry joins the nodes: that is its loop closure. Searching from it
  // too would cost a search per keyframe forever in a mapped place for ties the graph has.
  if (graph.smoother.IsFolded(key)) {
    ++folded_;
    return;
  }
  waiting_.push_back(key);
  while (static_cast<int>(waiting_.size()) > options_.max_waiting) waiting_.pop_front();
}

void LoopClosures::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  Examine(graph, out);
}

void LoopClosures::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Examine(graph, out);
  UseMatches(now_utime_, /*all=*/true, graph, out);
  for (auto& [trajectory, kept] : kept_) GiveUpHeld(&kept, &stats_);
  kept_.clear();
}

void LoopClosures::Examine(const GraphView& graph, EncounterSourceOutput* out) {
  if (graph.covariances == nullptr) return;
  // In arrival order; a keyframe not solved yet (it arrived in this very call) waits.
  std::deque<PoseKey> still_waiting;
  std::vector<BudgetRequest> ready;
  for (const PoseKey key : waiting_) {
    if (!graph.covariances->HasCovariance(key)) {
      still_waiting.push_back(key);
      continue;
    }
    BudgetRequest request{key, 0.0};
    if (budget_.bounded()) {
      if (const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory)) {
        request.driven_m = driven_.To(*record, key.index);
      }
    }
    ready.push_back(request);
  }
  waiting_ = std::move(still_waiting);
  budget_.Advance(now_utime_);
  const double most_per_keyframe =
      options_.max_candidates + (options_.wide_search ? options_.budget_wide_units : 0.0);
  budget_.Serve(ready, most_per_keyframe, [&](PoseKey key) {
    const double before = units_submitted_;
    ExamineKeyframe(key, graph);
    UseMatches(now_utime_, /*all=*/false, graph, out);
    return units_submitted_ - before;
  });
  UseMatches(now_utime_, /*all=*/false, graph, out);
}

void LoopClosures::UseMatches(int64_t now_utime, bool all, const GraphView& graph,
                              EncounterSourceOutput* out) {
  while (!matches_.empty() && (all || matches_.front().due_utime <= now_utime)) {
    const PendingMatch pending = std::move(matches_.front());
    matches_.pop_front();
    const std::optional<MatchResult> match = pending.result.get();
    if (pending.wide && match) ChargeWideBySize(match->search);
    if (!match || (pending.wide && !FoundPose(*match))) {
      ++stats_.no_match;
      continue;
    }
    const double min_score = pending.wide ? options_.wide_min_score : options_.min_score;
    // A wide match below wide_min_overlap may still be a weak hypothesis.
    const double min_overlap =
        pending.wide ? std::min(options_.wide_min_overlap, options_.wide_weak_min_overlap)
                     : options_.min_overlap;
    if (match->score < min_score || match->overlap < min_overlap) {
      ++stats_.weak_match;
      continue;
    }
    const Eigen::Matrix3d covariance =
        WithCovarianceFloor(match->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
    if (Mahalanobis2(pending.predicted.T_a_b, match->pose,
                     pending.predicted.covariance + covariance) > options_.gate_chi2) {
      ++stats_.gate_rejected;
      continue;
    }
    if (pending.wide && Ambiguous(pending, *match)) {
      ++stats_.gate_rejected;
      ++ambiguous_;
      continue;
    }
    if (pending.wide) {
      if (std::optional<Hypothesis> closure = RefineWide(pending, *match, graph)) {
        closure->weak = match->overlap < options_.wide_min_overlap;
        OfferWide(*closure, graph, out);
      }
      continue;
    }
    Emit(Hypothesis{pending.candidate, pending.key, match->pose, covariance, pending.key_utime},
         out);
  }
}

std::shared_ptr<const ScanReference> LoopClosures::Reference(const TrajectoryRecord& record,
                                                             const GraphView& graph, PoseKey center,
                                                             int half_width) {
  return references_.Get(
      record, DrawKeyframeSubmap(record, graph.smoother, center, half_width, options_.max_range_m),
      half_width);
}

bool LoopClosures::Ambiguous(const PendingMatch& pending, const MatchResult& wide) const {
  if (!pending.rival.valid()) return false;
  const std::optional<MatchResult> rival = pending.rival.get();
  if (!rival) return false;
  // The rival need not pass the wide bars: where the estimate puts the query, the reference
  // (drawn around the candidate) holds only part of what the query sees, while a copy nearer
  // the candidate is seen whole (in the test's periodic corridor the true pose scored 0.47-0.50
  // with overlap 0.66-0.68, the copy 0.91 and 0.98). A match that the estimate's own covariance
  // (without the drift model) accepts is evidence enough that the estimate is right there.
  const Eigen::Matrix3d undrifted = pending.predicted.covariance - pending.drift;
  const Eigen::Matrix3d rival_covariance =
      WithCovarianceFloor(rival->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
  if (Mahalanobis2(pending.predicted.T_a_b, rival->pose, undrifted + rival_covariance) >
      options_.gate_chi2) {
    return false;
  }
  const Eigen::Vector3d apart = PoseError(rival->pose, wide.pose);
  return apart.head<2>().norm() > options_.min_window_m ||
         std::abs(apart.z()) > options_.min_window_rad;
}

std::optional<LoopClosures::Hypothesis> LoopClosures::RefineWide(const PendingMatch& pending,
                                                                 const MatchResult& coarse,
                                                                 const GraphView& graph) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(pending.key.trajectory);
  if (record == nullptr || graph.covariances == nullptr) {
    ++stats_.no_match;
    return std::nullopt;
  }
  // The submap keyframe that looks nearest to where the query looks (the points
  // refine_look_ahead_m in front of each), far enough back to be a loop.
  const Pose2 ahead(options_.refine_look_ahead_m, 0.0, 0.0);
  const Eigen::Vector2d looked_at = Compose(coarse.pose, ahead).translation();
  auto apart = [&](const Pose2& pose) {
    return (Compose(pose, ahead).translation() - looked_at).norm();
  };
  const std::pair<int32_t, Pose2>* nearest = nullptr;
  for (const auto& entry : pending.submap_poses) {
    if (entry.first > pending.key.index - options_.min_index_gap) continue;
    if (nearest == nullptr || apart(entry.second) < apart(nearest->second)) nearest = &entry;
  }
  LocalMatchOptions window;
  window.match = options_.match;
  // The bars a refined match must pass below (its covariance is used only then).
  window.match.covariance_min_score = options_.min_score;
  window.match.covariance_min_overlap = options_.min_overlap;
  window.linear_window_m = options_.min_window_m;
  window.angular_window_rad = options_.min_window_rad;
  LocalMatchOptions small = window;
  small.linear_window_m = 0.5 * options_.min_window_m;
  small.angular_window_rad = 0.5 * options_.min_window_rad;
  // Of the keyframes that look near the same point, the one whose own scan the query matches
  // best at the coarse pose: the place submap holds every pass of the place at its estimate,
  // and passes the open loop drew apart are seen there as doubled walls. The coarse match
  // follows one pass; the geometrically nearest keyframe may lie on another (ACES 3 robots,
  // R3's key 170: matched its 94-97 s pass exactly, score 0.72-0.81 against each of those
  // scans, while the nearest keyframe, 76, was of the 186 s pass drawn 3 m off: no match
  // within the refinement's 0.4 m).
  if (nearest != nullptr && options_.refine_choice_radius_m > 0) {
    std::vector<SeenKeyframe> near;
    for (const auto& entry : pending.submap_poses) {
      if (entry.first > pending.key.index - options_.min_index_gap) continue;
      if (apart(entry.second) > options_.refine_choice_radius_m) continue;
      near.push_back({entry.first, entry.second,
                      Reference(*record, graph, PoseKey{pending.key.trajectory, entry.first}, 0)});
    }
    // Only the scores choose: no covariance (at 100 robots 44 % of a local match's CPU).
    LocalMatchOptions scored = small;
    scored.match.covariance = false;
    const int32_t seen = BestSeenKeyframe(near, *pending.query, coarse.pose, scored);
    for (const auto& entry : pending.submap_poses) {
      if (entry.first == seen) nearest = &entry;
    }
  }
  const PoseKey candidate{pending.key.trajectory, nearest ? nearest->first : 0};
  // Drawn at the estimates of the moment (a one-scan submap, at the identity, is kept).
  const std::shared_ptr<const ScanReference> scan =
      nearest == nullptr ? nullptr
      : options_.wide_refine_half_width > 0
          ? references_.BuildUnkept(
                *record, DrawKeyframeSubmap(*record, graph.smoother, candidate,
                                            options_.wide_refine_half_width, options_.max_range_m))
          : Reference(*record, graph, candidate, 0);
  const std::optional<PredictedRelativePose> predicted =
      scan ? PredictRelativePose(graph.covariances, candidate, pending.key) : std::nullopt;
  if (!predicted) {
    ++stats_.no_match;
    return std::nullopt;
  }
  // Its covariance only once it is the one kept (below): AddCovariance gives the same bits.
  LocalMatchOptions first = window;
  first.match.covariance = false;
  std::optional<MatchResult> match =
      MatchLocal(*scan, *pending.query, Between(nearest->second, coarse.pose), first);
  if (!match) {
    ++stats_.no_match;
    return std::nullopt;
  }
  // Then against the keyframe's scan alone (exact where the submap is bent by drift between
  // its keyframes), when that scan matches well enough on its own (a lattice score under
  // min_score is not searched for: the same match kept).
  bool replaced = false;
  if (options_.wide_refine_half_width > 0) {
    const std::shared_ptr<const ScanReference> alone = Reference(*record, graph, candidate, 0);
    LocalMatchOptions kept = small;
    kept.match.min_score = LatticeBarFor(options_.min_score, kept.match.min_score);
    const std::optional<MatchResult> exact =
        alone ? MatchLocal(*alone, *pending.query, match->pose, kept) : std::nullopt;
    if (exact && exact->score >= options_.min_score && exact->overlap >= options_.min_overlap) {
      match = exact;
      replaced = true;
    }
  }
  if (!replaced) AddCovariance(*scan, *pending.query, window.match, &*match);
  if (match->score < options_.min_score || match->overlap < options_.min_overlap) {
    ++stats_.weak_match;
    return std::nullopt;
  }
  const Eigen::Matrix3d covariance =
      WithCovarianceFloor(match->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
  const double tied_path_m =
      EstimatedPath(graph.smoother, candidate.trajectory, candidate.index, pending.key.index);
  if (!GateRefinedWide(*predicted, match->pose, covariance, tied_path_m, options_).passes) {
    ++stats_.gate_rejected;
    return std::nullopt;
  }
  return Hypothesis{candidate, pending.key, match->pose, covariance, pending.key_utime};
}

void LoopClosures::Emit(const Hypothesis& closure, EncounterSourceOutput* out) {
  if (!entered_[closure.key.trajectory]
           .emplace(closure.candidate.index, closure.key.index)
           .second) {
    ++stats_.repeated;
    return;
  }
  ++stats_.accepted;
  int32_t& last = last_closure_[closure.key.trajectory];
  last = std::max(last, closure.key.index);
  EncounterConstraint constraint;
  constraint.a = closure.candidate;
  constraint.b = closure.key;
  constraint.measured_T_a_b = closure.measured;
  constraint.covariance = closure.covariance;
  constraint.utime = closure.key_utime;
  constraint.source = name();
  constraint.kind = ConstraintKind::kLoopClosure;
  out->constraints.push_back(constraint);
  int32_t& quiet = quiet_until_[closure.key.trajectory];
  quiet = std::max(quiet, closure.key.index + 1 + options_.cooldown_keyframes);
}

double LargestTranslationSigma(const Eigen::Matrix3d& covariance) {
  const double a = covariance(0, 0), b = covariance(0, 1), c = covariance(1, 1);
  const double half_gap = 0.5 * (a - c);
  return std::sqrt(std::max(0.0, 0.5 * (a + c) + std::sqrt(half_gap * half_gap + b * b)));
}

bool WidePairMayEnter(const WideEvidence& first, const WideEvidence& second, double separation_m,
                      const LoopClosureOptions& options) {
  if (!first.weak && !second.weak) return true;
  if (first.weak && second.weak) return false;
  const WideEvidence& strong = first.weak ? second : first;
  return separation_m >= options.wide_pair_min_separation_m &&
         strong.sigma_m <= options.wide_weak_partner_max_sigma_m;
}

bool EstimatedWhereTheMapHasBeen(const Smoother& smoother, PoseKey key, int min_index_gap,
                                 double radius_m) {
  if (!smoother.HasPose(key)) return false;
  const Eigen::Vector2d at = smoother.FramePose(key).translation();
  for (int32_t i = 0; i <= key.index - min_index_gap; ++i) {
    const PoseKey older{key.trajectory, i};
    if (smoother.HasPose(older) &&
        (smoother.FramePose(older).translation() - at).norm() <= radius_m) {
      return true;
    }
  }
  return false;
}

Eigen::Matrix3d WideDriftCovariance(double path_m, const LoopClosureOptions& options) {
  const double m = options.drift_per_m * path_m, rad = options.drift_rad_per_m * path_m;
  return Eigen::Vector3d(m * m, m * m, rad * rad).asDiagonal().toDenseMatrix();
}

RefinedWideGate GateRefinedWide(const PredictedRelativePose& predicted, const Pose2& match,
                                const Eigen::Matrix3d& match_covariance, double tied_path_m,
                                const LoopClosureOptions& options) {
  // The drift the estimate may not know of grows with the path from the keyframe the closure
  // ties (the refined one), not from the keyframe the search was drawn around, which may lie
  // far back: 20 x 300 simulation, R5 (keyframes 316-336 of one straight corridor): drawn
  // 130 m of path back (drift 3.9 m), the match 7 m off (a repeated room) passed at chi2 3.2;
  // with the 10.6 m path to 316 (0.32 m) its chi2 is 451.
  const Eigen::Matrix3d drift = WideDriftCovariance(tied_path_m, options);
  RefinedWideGate gate;
  gate.drift_sigma_m = std::sqrt(drift(0, 0));
  gate.chi2 = Mahalanobis2(predicted.T_a_b, match, predicted.covariance + drift + match_covariance);
  gate.passes = !(gate.chi2 > options.gate_chi2);
  return gate;
}

double WidePairInconsistency2(const PredictedRelativePose& candidates, const Pose2& first,
                              const Eigen::Matrix3d& first_covariance,
                              PredictedRelativePose queries, const Pose2& second,
                              const Eigen::Matrix3d& second_covariance, double query_path_m,
                              const LoopClosureOptions& options) {
  // Rotation only: widened in translation too, intel-1 went 0.0239 -> 0.0245 m.
  queries.covariance(2, 2) += WideDriftCovariance(query_path_m, options)(2, 2);
  return PairwiseInconsistency2(candidates, first, first_covariance, queries, second,
                                second_covariance);
}

void LoopClosures::OfferWide(const Hypothesis& hypothesis, const GraphView& graph,
                             EncounterSourceOutput* out) {
  std::deque<Hypothesis>& kept = kept_[hypothesis.key.trajectory];
  // Hypotheses too old to pair with this one (or any later one) are given up.
  GiveUpHeldOlderThan(
      hypothesis.key.index, options_.wide_pair_max_gap,
      [](const Hypothesis& h) { return h.key.index; }, &kept, &stats_);
  if (graph.covariances != nullptr) {
    // A pair needs a query the estimate puts where the map has been. Where it puts both in
    // space never mapped, nothing checks the estimate (the rival finds nothing to match), and a
    // place seen for the first time matches a look-alike of it as well as a returning robot its
    // old place: two such matches agree (the periodic corridor's north end, reached for the
    // first time 113 m into the ring, matched the south corridor's end 10 m away: chi2 7.8-8.8
    // under a drift of 3.3-3.5 m, entered, the map's mean error 5.5 m).
    const bool checked = EstimatedWhereTheMapHasBeen(
        graph.smoother, hypothesis.key, options_.min_index_gap, options_.max_distance_m);
    // The newest agreeing hypothesis: the two views of the loop's far end are different
    // places (the query moved on), so an aliased spot cannot vouch for itself.
    for (auto it = kept.rbegin(); it != kept.rend(); ++it) {
      if (hypothesis.key.index - it->key.index < options_.wide_pair_min_gap) continue;
      if (!checked && !EstimatedWhereTheMapHasBeen(graph.smoother, it->key, options_.min_index_gap,
                                                   options_.max_distance_m)) {
        continue;
      }
      // Both solves at once: they share R's wide bottom rows.
      const std::vector<std::optional<PredictedRelativePose>> predicted = PredictRelativePoses(
          graph.covariances, {{it->candidate, hypothesis.candidate}, {it->key, hypothesis.key}});
      const std::optional<PredictedRelativePose>& candidates = predicted[0];
      const std::optional<PredictedRelativePose>& keys = predicted[1];
      if (!candidates || !keys) continue;
      const double query_path_m = EstimatedPath(graph.smoother, hypothesis.key.trajectory,
                                                it->key.index, hypothesis.key.index);
      if (WidePairInconsistency2(*candidates, it->measured, it->covariance, *keys,
                                 hypothesis.measured, hypothesis.covariance, query_path_m,
                                 options_) > options_.wide_pair_chi2) {
        continue;
      }
      if (!WidePairMayEnter({it->weak, LargestTranslationSigma(it->covariance)},
                            {hypothesis.weak, LargestTranslationSigma(hypothesis.covariance)},
                            keys->T_a_b.translation().norm(), options_)) {
        continue;
      }
      const Hypothesis first = *it;
      // Both enter; the others are dropped: the graph changes and they were made against
      // the old estimate.
      DropHeld(&kept, &stats_);
      Emit(first, out);
      Emit(hypothesis, out);
      LogDebug("loop: wide closure pair " + Key(first.candidate).ToString() + "-" +
               Key(first.key).ToString() + " and " + Key(hypothesis.candidate).ToString() + "-" +
               Key(hypothesis.key).ToString());
      return;
    }
  }
  Hold(hypothesis, options_.wide_max_kept, &kept, &stats_);
}

void LoopClosures::ExamineKeyframe(PoseKey key, const GraphView& graph) {
  Smoother* smoother = graph.covariances;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index >= record->num_keyframes()) return;
  if (record->scans[static_cast<size_t>(key.index)].ranges.empty()) return;
  if (options_.max_candidates == 0) return;
  if (const auto quiet = quiet_until_.find(key.trajectory);
      quiet != quiet_until_.end() && key.index < quiet->second) {
    return;
  }
  const int last_candidate = key.index - options_.min_index_gap;
  if (last_candidate < 0) return;

  // Cheap prefilter on the estimates: within the disc plus 3 sigma of the keyframe's own
  // uncertainty (twice: the candidate's is usually smaller, the gauge being at index 0).
  const Pose2 T_local_key = smoother->FramePose(key);
  std::vector<std::pair<double, int>> near;
  size_t within_disc = 0;
  for (int j = 0; j <= last_candidate; ++j) {
    const PoseKey candidate{key.trajectory, j};
    if (!smoother->HasPose(candidate)) continue;
    const double distance =
        (smoother->FramePose(candidate).translation() - T_local_key.translation()).norm();
    near.emplace_back(distance, j);
    if (distance <= options_.max_distance_m) ++within_disc;
  }
  // The gate below examines only the nearest max_examined: when that many lie in the disc,
  // the slack would only add farther ones, never examined, and its covariance is not needed.
  const size_t max_examined = static_cast<size_t>(4 * options_.max_candidates);
  const size_t max_chosen = static_cast<size_t>(options_.max_candidates);
  const double radius = within_disc >= max_examined
                            ? options_.max_distance_m
                            : options_.max_distance_m + PrefilterSlack(smoother, key);
  near.erase(std::remove_if(near.begin(), near.end(),
                            [radius](const auto& n) { return n.first > radius; }),
             near.end());
  std::sort(near.begin(), near.end());

  // The joint-covariance gate, nearest first; candidates apart by more than a submap.
  std::vector<std::pair<int, PredictedRelativePose>> chosen;
  const auto takes = [&](size_t n) {
    const int j = near[n].second;
    if (Saturated(*record, PoseKey{key.trajectory, j}, key)) {
      ++saturated_;
      return false;
    }
    return std::none_of(chosen.begin(), chosen.end(), [&](const auto& c) {
      return std::abs(c.first - j) <= options_.submap_half_width;
    });
  };
  // A candidate predicted inside the disc passes the gate whatever its covariance (the
  // distance from the disc is 0): the nearest ones usually are, and their covariances,
  // needed for the match, are solved together (the solves' cost is reading R's wide
  // bottom rows, which they share). The first one outside the disc ends this part.
  size_t n = 0;
  std::vector<std::pair<PoseKey, PoseKey>> inside;
  for (; n < near.size() && n < max_examined && chosen.size() < max_chosen; ++n) {
    if (!takes(n)) continue;
    const PoseKey candidate{key.trajectory, near[n].second};
    const std::optional<RelativePoseQuery> query = RelativePoseQueryOf(*smoother, candidate, key);
    if (!query) continue;
    if (query->T_a_b.translation().norm() > options_.max_distance_m) break;
    chosen.emplace_back(candidate.index, PredictedRelativePose{});
    inside.emplace_back(candidate, key);
  }
  const std::vector<std::optional<PredictedRelativePose>> predicted_inside =
      PredictRelativePoses(smoother, inside);
  for (size_t c = 0; c < inside.size(); ++c) chosen[c].second = *predicted_inside[c];
  for (; n < near.size() && n < max_examined && chosen.size() < max_chosen; ++n) {
    if (!takes(n)) continue;
    const int j = near[n].second;
    const std::optional<PredictedRelativePose> predicted =
        PredictRelativePose(smoother, PoseKey{key.trajectory, j}, key);
    if (!predicted) continue;
    if (DistanceFromDisc2(predicted->T_a_b.translation(),
                          predicted->covariance.topLeftCorner<2, 2>(),
                          options_.max_distance_m) > options_.candidate_chi2) {
      continue;
    }
    chosen.emplace_back(j, *predicted);
  }

  // The jobs own what they read: the query's points, the submap (immutable once built).
  const auto query =
      std::make_shared<const PointCloud>(KeyframePoints(*record, key.index, options_.max_range_m));
  for (const auto& [j, predicted] : chosen) {
    Submit(PoseKey{key.trajectory, j}, key, predicted, Eigen::Matrix3d::Zero(), false, *record,
           graph, query);
  }
  if (options_.wide_search) SubmitWide(key, graph, *record, query);
}

bool LoopClosures::Saturated(const TrajectoryRecord& record, PoseKey candidate, PoseKey key) {
  if (options_.saturation_m <= 0) return false;
  const auto entered = entered_.find(key.trajectory);
  if (entered == entered_.end()) return false;
  const double at_key = driven_.To(record, key.index);
  const double at_candidate = driven_.To(record, candidate.index);
  for (const auto& [a, b] : entered->second) {
    if (std::abs(driven_.To(record, b) - at_key) < options_.saturation_m &&
        std::abs(driven_.To(record, a) - at_candidate) < options_.saturation_m) {
      return true;
    }
  }
  return false;
}

bool LoopClosures::NeedsWideWindow(const Eigen::Matrix3d& covariance) const {
  return 3.0 * LargestSigma(covariance.topLeftCorner<2, 2>()) > options_.max_window_m ||
         3.0 * std::sqrt(std::max(0.0, covariance(2, 2))) > options_.max_window_rad;
}

void LoopClosures::SubmitWide(PoseKey key, const GraphView& graph, const TrajectoryRecord& record,
                              const std::shared_ptr<const PointCloud>& query) {
  Smoother* smoother = graph.covariances;
  int32_t& next = next_wide_[key.trajectory];
  if (key.index < next) return;
  // Closures found lately keep the estimate good enough for the local window.
  if (const auto last = last_closure_.find(key.trajectory);
      last != last_closure_.end() && key.index - last->second < options_.wide_quiet_keyframes) {
    return;
  }
  const int last_candidate = key.index - options_.min_index_gap;
  // The drift the estimate may not know of grows with the path driven from the candidate
  // to the keyframe (the smoother's covariance trusts the scan-matched odometry too much:
  // on ACES 1-sigma 0.5-1 m where the return was metres off).
  std::vector<double> along(static_cast<size_t>(key.index) + 1, 0.0);
  for (int i = key.index - 1; i >= 0; --i) {
    const PoseKey a{key.trajectory, i}, b{key.trajectory, i + 1};
    const double step =
        smoother->HasPose(a) && smoother->HasPose(b)
            ? (smoother->FramePose(a).translation() - smoother->FramePose(b).translation()).norm()
            : 0.0;
    along[static_cast<size_t>(i)] = along[static_cast<size_t>(i) + 1] + step;
  }
  auto drift = [&](int j) { return WideDriftCovariance(along[static_cast<size_t>(j)], options_); };
  const Pose2 T_local_key = smoother->FramePose(key);
  // The candidate the estimate and the drift make likeliest within reach (nearest on ties).
  int best = -1;
  double best_normalised = 0.0, best_distance = 0.0;
  for (int j = 0; j <= last_candidate; ++j) {
    const PoseKey candidate{key.trajectory, j};
    if (!smoother->HasPose(candidate)) continue;
    // The drift alone chooses (the keyframe's marginal covariance is measured from the
    // trajectory's start, not from the candidate); the joint one is added below.
    const Eigen::Matrix3d covariance = drift(j);
    if (!NeedsWideWindow(covariance)) continue;
    const double sigma = LargestSigma(covariance.topLeftCorner<2, 2>());
    const double distance =
        (smoother->FramePose(candidate).translation() - T_local_key.translation()).norm();
    const double beyond = distance - options_.max_distance_m;
    if (beyond > std::min(options_.wide_sigmas * sigma, options_.wide_max_window_m)) continue;
    const double normalised = std::max(0.0, beyond) / sigma;
    if (best < 0 || normalised < best_normalised ||
        (normalised == best_normalised && distance < best_distance)) {
      best = j;
      best_normalised = normalised;
      best_distance = distance;
    }
  }
  if (best < 0) return;
  const PoseKey candidate{key.trajectory, best};
  std::optional<PredictedRelativePose> predicted = PredictRelativePose(smoother, candidate, key);
  if (!predicted) return;
  const Eigen::Matrix3d extra = drift(best);
  predicted->covariance += extra;
  next = key.index + options_.wide_every_keyframes;
  Submit(candidate, key, *predicted, extra, true, record, graph, query);
}

void LoopClosures::Submit(PoseKey candidate, PoseKey key, const PredictedRelativePose& predicted,
                          const Eigen::Matrix3d& drift, bool wide, const TrajectoryRecord& record,
                          const GraphView& graph, const std::shared_ptr<const PointCloud>& query) {
  ++stats_.candidates;
  units_submitted_ += wide ? options_.budget_wide_units : 1.0;
  // The wide window's half width (the branch and bound searches it around the prediction).
  const double sigma_xy = LargestSigma(predicted.covariance.topLeftCorner<2, 2>());
  const double sigma_theta = std::sqrt(std::max(0.0, predicted.covariance(2, 2)));
  const double linear = std::clamp(options_.wide_sigmas * sigma_xy, options_.max_window_m,
                                   options_.wide_max_window_m);
  std::optional<SubmapDrawing> by_place;
  if (wide && options_.wide_submap_by_place) {
    PlaceSubmapOptions place;
    if (options_.wide_submap_place_keeps_index) {
      place.keep_first = candidate.index - options_.wide_submap_half_width;
      place.keep_last = candidate.index + options_.wide_submap_half_width;
    }
    place.radius_m = linear + options_.max_distance_m;
    place.last_index = key.index - options_.min_index_gap;
    place.max_keyframes = options_.wide_submap_max_keyframes;
    place.spacing_m = options_.wide_submap_spacing_m;
    place.spacing_rad = options_.wide_submap_spacing_rad;
    // Near the candidate's own estimate (the origin of its frame), not the prediction.
    by_place = DrawKeyframeSubmapNear(record, graph.smoother, candidate, Eigen::Vector2d::Zero(),
                                      place, options_.max_range_m);
  }
  const std::shared_ptr<const ScanReference> submap =
      by_place ? references_.BuildUnkept(record, *by_place)
               : Reference(record, graph, candidate,
                           wide ? options_.wide_submap_half_width : options_.submap_half_width);
  if (!submap) {
    ++stats_.no_match;
    return;
  }
  PendingMatch pending;
  pending.candidate = candidate;
  pending.key = key;
  pending.key_utime = record.utimes[static_cast<size_t>(key.index)];
  pending.due_utime =
      pool_ ? schedule_.DueUtime(pending.key_utime) : std::numeric_limits<int64_t>::min();
  pending.predicted = predicted;
  pending.wide = wide;
  pending.drift = drift;
  if (by_place) {
    pending.query = query;
    pending.submap_poses.assign(by_place->T_center_keyframes.begin(),
                                by_place->T_center_keyframes.end());
  } else if (wide) {
    pending.query = query;
    const Pose2 T_local_candidate = graph.smoother.FramePose(candidate);
    const int32_t first = std::max(0, candidate.index - options_.wide_submap_half_width);
    const int32_t last =
        std::min(record.num_keyframes() - 1, candidate.index + options_.wide_submap_half_width);
    for (int32_t i = first; i <= last; ++i) {
      const PoseKey key_i{candidate.trajectory, i};
      if (!graph.smoother.HasPose(key_i)) continue;
      pending.submap_poses.emplace_back(
          i, Between(T_local_candidate, graph.smoother.FramePose(key_i)));
    }
  }
  const Pose2 guess = predicted.T_a_b;
  if (wide) {
    ++wide_searches_;
    // Branch and bound over the lattice around the prediction, as GlobalSearch does over a
    // whole grid: a higher lattice bar (the acceptance bar) prunes more.
    const double resolution = submap->geometry().resolution;
    SearchWindow window;
    window.center = guess;
    window.angle_step_rad = AngleStepForRange(resolution, MaxPointRange(*query));
    const double angular =
        std::min(options_.wide_sigmas * sigma_theta, options_.wide_max_window_rad);
    window.half_angles = static_cast<int>(std::ceil(angular / window.angle_step_rad));
    window.half_cells_x = window.half_cells_y = static_cast<int>(std::ceil(linear / resolution));
    MatchOptions match = options_.match;
    match.min_score = std::max(match.min_score, options_.wide_min_score);
    // UseMatches' bars for a wide match (a weak hypothesis included).
    match.covariance_min_score = options_.wide_min_score;
    match.covariance_min_overlap =
        std::min(options_.wide_min_overlap, options_.wide_weak_min_overlap);
    auto job = [submap, query, window, match] {
      return WideSearch(*submap, *query, window, match);
    };
    pending.result =
        RunMatch(pool_, MatchTag{key, candidate, MatchKind::kLoopWide}, std::move(job));
    // The rival: the local window the prediction would have without the drift model.
    const Eigen::Matrix3d undrifted = predicted.covariance - drift;
    LocalMatchOptions local;
    local.match = options_.match;
    local.linear_window_m = std::clamp(3.0 * LargestSigma(undrifted.topLeftCorner<2, 2>()),
                                       options_.min_window_m, options_.max_window_m);
    local.angular_window_rad = std::clamp(3.0 * std::sqrt(std::max(0.0, undrifted(2, 2))),
                                          options_.min_window_rad, options_.max_window_rad);
    auto rival = [submap, query, guess, local] {
      return MatchLocal(*submap, *query, guess, local);
    };
    pending.rival =
        RunMatch(pool_, MatchTag{key, candidate, MatchKind::kLoopRival}, std::move(rival));
  } else {
    LocalMatchOptions window;
    window.match = options_.match;
    window.match.covariance_min_score = options_.min_score;  // UseMatches' bars
    window.match.covariance_min_overlap = options_.min_overlap;
    // UseMatches drops a lattice score under min_score: the search need not find it.
    window.match.min_score = LatticeBarFor(options_.min_score, window.match.min_score);
    window.linear_window_m =
        std::clamp(3.0 * sigma_xy, options_.min_window_m, options_.max_window_m);
    window.angular_window_rad =
        std::clamp(3.0 * sigma_theta, options_.min_window_rad, options_.max_window_rad);
    auto job = [submap, query, guess, window] {
      return MatchLocal(*submap, *query, guess, window);
    };
    pending.result =
        RunMatch(pool_, MatchTag{key, candidate, MatchKind::kLoopLocal}, std::move(job));
  }
  matches_.push_back(std::move(pending));
}

int32_t BestSeenKeyframe(const std::vector<SeenKeyframe>& keyframes, const PointCloud& query,
                         const Pose2& T_submap_query, const LocalMatchOptions& window) {
  int32_t best = -1;
  double best_score = 0.0;
  for (const SeenKeyframe& keyframe : keyframes) {
    if (keyframe.scan == nullptr) continue;
    // Only the lattice scores choose (MatchLocal's score, without its refinement).
    const std::optional<double> seen = LocalLatticeScore(
        *keyframe.scan, query, Between(keyframe.T_submap_keyframe, T_submap_query), window);
    if (seen && *seen > best_score) {
      best_score = *seen;
      best = keyframe.index;
    }
  }
  return best;
}

}  // namespace anchormap
