#pragma once
// An encounter in the relative formulation (docs/METHOD.md section 4): four variables,
// two poses in their trajectories' local frames and the two trajectories' anchors
// T_global_local. Prediction h = (A_a (+) x_a)^-1 (+) (A_b (+) x_b), the pose b seen
// from pose a in the global frame; residual h - z. Jacobians are analytic (iSAM 1
// differentiates this factor numerically) and tested against numeric differences.

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"

namespace anchormap {

struct EncounterFactor {
  PoseKey a;
  PoseKey b;
  Pose2 measured_T_a_b;
  Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Identity();

  // Jacobian order: x_a, x_b, A_a, A_b.
  std::vector<Key> keys() const { return {a, b, AnchorKey{a.trajectory}, AnchorKey{b.trajectory}}; }

  // J (if not null) points to 4 matrices, in keys() order.
  Eigen::Vector3d Error(const Pose2& T_local_a, const Pose2& T_local_b,
                        const Pose2& T_global_local_a, const Pose2& T_global_local_b,
                        Eigen::Matrix3d* J) const {
    if (!J) {
      return PoseError(
          Between(Compose(T_global_local_a, T_local_a), Compose(T_global_local_b, T_local_b)),
          measured_T_a_b);
    }
    Eigen::Matrix3d dga_dA, dga_dx, dgb_dA, dgb_dx, dh_dga, dh_dgb;
    const Pose2 global_a = Compose(T_global_local_a, T_local_a, &dga_dA, &dga_dx);
    const Pose2 global_b = Compose(T_global_local_b, T_local_b, &dgb_dA, &dgb_dx);
    const Pose2 h = Between(global_a, global_b, &dh_dga, &dh_dgb);
    J[0] = dh_dga * dga_dx;
    J[1] = dh_dgb * dgb_dx;
    J[2] = dh_dga * dga_dA;
    J[3] = dh_dgb * dgb_dA;
    return PoseError(h, measured_T_a_b);
  }
};

}  // namespace anchormap
