#include "server/relative_pose.h"

#include <limits>
#include <vector>

#include <Eigen/Cholesky>

#include "common/geometry/numeric_diff.h"

namespace anchormap {

bool InOneFrame(const Smoother& smoother, TrajectoryId a, TrajectoryId b) {
  if (a == b) return true;
  return smoother.IsAnchored(a) && smoother.IsAnchored(b) &&
         smoother.GroupRoot(a) == smoother.GroupRoot(b);
}

TrajectoryFrame FrameOf(const Smoother& smoother, TrajectoryId id) {
  const bool anchored = smoother.IsAnchored(id);
  return {anchored, anchored ? smoother.GroupRoot(id) : id};
}

TrajectoryFrames FramesOf(const TrajectoryTable& table, const Smoother& smoother) {
  TrajectoryFrames frames;
  frames.reserve(table.records().size());
  for (const TrajectoryRecord& record : table.records()) {
    frames.emplace_back(record.solver_id, FrameOf(smoother, record.solver_id));
  }
  return frames;
}

std::optional<PredictedRelativePose> PredictRelativePose(Smoother* smoother, PoseKey a, PoseKey b) {
  return PredictRelativePose(smoother, a, b, nullptr);
}

std::optional<RelativePoseQuery> RelativePoseQueryOf(const Smoother& smoother, PoseKey a,
                                                     PoseKey b) {
  if (!InOneFrame(smoother, a.trajectory, b.trajectory)) return std::nullopt;
  // Only from a solved graph: a covariance read across a pending merge or anchor would
  // describe the graph before it (MappingServer solves before its sources see one).
  if (!smoother.IsSolved(a) || !smoother.IsSolved(b)) return std::nullopt;
  RelativePoseQuery out;
  if (a.trajectory == b.trajectory) {
    Eigen::Matrix3d J_a, J_b;
    out.T_a_b = Between(smoother.FramePose(a), smoother.FramePose(b), &J_a, &J_b);
    out.covariance = {{a, b}, {J_a, J_b}};
  } else {
    const AnchorKey anchor_a{a.trajectory}, anchor_b{b.trajectory};
    if (!smoother.IsSolved(anchor_a) || !smoother.IsSolved(anchor_b)) {
      return std::nullopt;
    }
    Eigen::Matrix3d dga_dA, dga_dx, dgb_dA, dgb_dx, dh_dga, dh_dgb;
    const Pose2 global_a =
        Compose(smoother.Value(anchor_a), smoother.FramePose(a), &dga_dA, &dga_dx);
    const Pose2 global_b =
        Compose(smoother.Value(anchor_b), smoother.FramePose(b), &dgb_dA, &dgb_dx);
    out.T_a_b = Between(global_a, global_b, &dh_dga, &dh_dgb);
    out.covariance = {{a, b, anchor_a, anchor_b},
                      {dh_dga * dga_dx, dh_dgb * dgb_dx, dh_dga * dga_dA, dh_dgb * dgb_dA}};
  }
  return out;
}

std::optional<PredictedRelativePose> PredictRelativePose(Smoother* smoother, PoseKey a, PoseKey b,
                                                         const EnoughCovariance& enough) {
  const std::optional<RelativePoseQuery> query = RelativePoseQueryOf(*smoother, a, b);
  if (!query) return std::nullopt;
  PredictedRelativePose out;
  out.T_a_b = query->T_a_b;
  if (!enough) {
    out.covariance =
        smoother->ProjectedCovariance(query->covariance.keys, query->covariance.jacobians);
  } else {
    const Pose2 T_a_b = out.T_a_b;
    out.partial = !smoother->ProjectedCovarianceUntil(
        query->covariance.keys, query->covariance.jacobians,
        [&enough, &T_a_b](const Eigen::Matrix3d& so_far) { return enough(T_a_b, so_far); },
        &out.covariance);
  }
  return out;
}

std::vector<std::optional<PredictedRelativePose>> PredictRelativePoses(
    Smoother* smoother, const std::vector<std::pair<PoseKey, PoseKey>>& pairs) {
  std::vector<std::optional<PredictedRelativePose>> out(pairs.size());
  std::vector<Smoother::CovarianceQuery> queries;
  std::vector<size_t> asked;  // the pairs with a query, in queries' order
  for (size_t i = 0; i < pairs.size(); ++i) {
    std::optional<RelativePoseQuery> query =
        RelativePoseQueryOf(*smoother, pairs[i].first, pairs[i].second);
    if (!query) continue;
    out[i] = PredictedRelativePose{query->T_a_b};
    queries.push_back(std::move(query->covariance));
    asked.push_back(i);
  }
  const std::vector<Eigen::Matrix3d> covariances = smoother->ProjectedCovariances(queries);
  for (size_t g = 0; g < asked.size(); ++g) out[asked[g]]->covariance = covariances[g];
  return out;
}

double Mahalanobis2(const Pose2& predicted, const Pose2& measured,
                    const Eigen::Matrix3d& covariance) {
  const Eigen::Vector3d error = PoseError(predicted, measured);
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(0.5 * (covariance + covariance.transpose()));
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || ldlt.vectorD().minCoeff() <= 0.0) {
    return std::numeric_limits<double>::infinity();
  }
  return error.dot(ldlt.solve(error));
}

double PairwiseInconsistency2(const PredictedRelativePose& a1_a2, const Pose2& c1,
                              const Eigen::Matrix3d& c1_covariance,
                              const PredictedRelativePose& b1_b2, const Pose2& c2,
                              const Eigen::Matrix3d& c2_covariance) {
  // c2 predicted from c1: T_a2_b2 = T_a2_a1 (+) T_a1_b1 (+) T_b1_b2.
  auto predict = [](const Eigen::VectorXd& v) -> Eigen::Vector3d {
    const Pose2 a1_a2 = Pose2(v[0], v[1], v[2]);
    const Pose2 a1_b1 = Pose2(v[3], v[4], v[5]);
    const Pose2 b1_b2 = Pose2(v[6], v[7], v[8]);
    return Compose(a1_a2.Inverse(), Compose(a1_b1, b1_b2)).vector();
  };
  Eigen::VectorXd x(9);
  x << a1_a2.T_a_b.vector(), c1.vector(), b1_b2.T_a_b.vector();
  const Eigen::Matrix<double, 3, Eigen::Dynamic> J = NumericJacobian(predict, x);
  Eigen::Matrix<double, 9, 9> blocks = Eigen::Matrix<double, 9, 9>::Zero();
  blocks.block<3, 3>(0, 0) = a1_a2.covariance;
  blocks.block<3, 3>(3, 3) = c1_covariance;
  blocks.block<3, 3>(6, 6) = b1_b2.covariance;
  const Eigen::Matrix3d covariance = J * blocks * J.transpose() + c2_covariance;
  return Mahalanobis2(Pose2::FromVector(predict(x)), c2, covariance);
}

}  // namespace anchormap
