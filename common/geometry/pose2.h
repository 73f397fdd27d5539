#pragma once
// SE(2) poses (x, y, theta) and the operations of docs/METHOD.md section 1.
//
// Naming: a pose T_a_b places frame b in frame a (small_gicp's T_target_source);
// Compose(T_a_b, T_b_c) = T_a_c and Between(T_w_a, T_w_b) = T_a_b, the pose of b seen
// from a, which the thesis writes "b (-) a". Angles are wrapped to (-pi, pi].

#include <cmath>

#include <Eigen/Core>

#include "common/geometry/angle.h"

namespace anchormap {

class Pose2 {
 public:
  Pose2() = default;
  Pose2(double x, double y, double theta) : x_(x), y_(y), theta_(WrapAngle(theta)) {}
  static Pose2 FromVector(const Eigen::Vector3d& v) { return Pose2(v.x(), v.y(), v.z()); }

  double x() const { return x_; }
  double y() const { return y_; }
  double theta() const { return theta_; }
  Eigen::Vector2d translation() const { return {x_, y_}; }
  Eigen::Vector3d vector() const { return {x_, y_, theta_}; }
  Eigen::Matrix2d rotation() const;

  // The inverse pose: Compose(p, p.Inverse()) is the identity.
  Pose2 Inverse() const;
  // A point given in this pose's frame, expressed in the parent frame.
  Eigen::Vector2d TransformPoint(const Eigen::Vector2d& point) const;

  bool IsFinite() const;

 private:
  double x_ = 0.0;
  double y_ = 0.0;
  double theta_ = 0.0;
};

// T_a_c = T_a_b (+) T_b_c. Optional Jacobians are d(result)/d(T_a_b) and
// d(result)/d(T_b_c) with respect to the plain (x, y, theta) coordinates.
Pose2 Compose(const Pose2& T_a_b, const Pose2& T_b_c, Eigen::Matrix3d* J_ab = nullptr,
              Eigen::Matrix3d* J_bc = nullptr);

// cos and sin of a pose's angle: a caller that evaluates many factors at the same poses
// (the smoother's gradient passes) computes them once per pose, not once per factor.
struct CosSin {
  double c = 1.0;
  double s = 0.0;
  static CosSin Of(double angle) { return {std::cos(angle), std::sin(angle)}; }
};

// Compose without Jacobians, `rotation_a_b` = CosSin::Of(T_a_b.theta()) given (the same
// bits): the map publication composes every keyframe with its trajectory's anchor.
Pose2 Compose(const Pose2& T_a_b, const CosSin& rotation_a_b, const Pose2& T_b_c);

// T_a_b = T_w_b (-) T_w_a: the pose b expressed in the frame of a. Optional Jacobians
// d(result)/d(T_w_a) and d(result)/d(T_w_b).
Pose2 Between(const Pose2& T_w_a, const Pose2& T_w_b, Eigen::Matrix3d* J_a = nullptr,
              Eigen::Matrix3d* J_b = nullptr);
// The same with `rotation_a` = CosSin::Of(T_w_a.theta()) given (the same bits).
Pose2 Between(const Pose2& T_w_a, const CosSin& rotation_a, const Pose2& T_w_b,
              Eigen::Matrix3d* J_a = nullptr, Eigen::Matrix3d* J_b = nullptr);

// Difference of two poses as a vector (x, y, wrapped theta): the residual of a
// measurement `measured` against a prediction `predicted`.
Eigen::Vector3d PoseError(const Pose2& predicted, const Pose2& measured);

// The pose a `fraction` of the way from a to b: linear in x and y, the short way round in
// theta (0 gives a, 1 gives b). Used to read odometry between two time stamps.
Pose2 Interpolate(const Pose2& a, const Pose2& b, double fraction);

}  // namespace anchormap
