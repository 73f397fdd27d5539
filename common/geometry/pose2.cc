#include "common/geometry/pose2.h"

#include <cmath>

namespace anchormap {

Eigen::Matrix2d Pose2::rotation() const {
  const double c = std::cos(theta_), s = std::sin(theta_);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

Pose2 Pose2::Inverse() const {
  const double c = std::cos(theta_), s = std::sin(theta_);
  return Pose2(-c * x_ - s * y_, s * x_ - c * y_, -theta_);
}

Eigen::Vector2d Pose2::TransformPoint(const Eigen::Vector2d& point) const {
  return rotation() * point + translation();
}

bool Pose2::IsFinite() const {
  return std::isfinite(x_) && std::isfinite(y_) && std::isfinite(theta_);
}

Pose2 Compose(const Pose2& T_a_b, const Pose2& T_b_c, Eigen::Matrix3d* J_ab,
              Eigen::Matrix3d* J_bc) {
  const double c = std::cos(T_a_b.theta()), s = std::sin(T_a_b.theta());
  const double dx = T_b_c.x(), dy = T_b_c.y();
  if (J_ab) {
    // d/d(x_b, y_b, th_b) of (x_b + c dx - s dy, y_b + s dx + c dy, th_b + th_d).
    *J_ab << 1, 0, -s * dx - c * dy,  //
        0, 1, c * dx - s * dy,        //
        0, 0, 1;
  }
  if (J_bc) {
    *J_bc << c, -s, 0,  //
        s, c, 0,        //
        0, 0, 1;
  }
  return Pose2(T_a_b.x() + c * dx - s * dy, T_a_b.y() + s * dx + c * dy,
               T_a_b.theta() + T_b_c.theta());
}

Pose2 Compose(const Pose2& T_a_b, const CosSin& rotation_a_b, const Pose2& T_b_c) {
  const double c = rotation_a_b.c, s = rotation_a_b.s;
  const double dx = T_b_c.x(), dy = T_b_c.y();
  return Pose2(T_a_b.x() + c * dx - s * dy, T_a_b.y() + s * dx + c * dy,
               T_a_b.theta() + T_b_c.theta());
}

Pose2 Between(const Pose2& T_w_a, const Pose2& T_w_b, Eigen::Matrix3d* J_a, Eigen::Matrix3d* J_b) {
  return Between(T_w_a, CosSin::Of(T_w_a.theta()), T_w_b, J_a, J_b);
}

Pose2 Between(const Pose2& T_w_a, const CosSin& rotation_a, const Pose2& T_w_b,
              Eigen::Matrix3d* J_a, Eigen::Matrix3d* J_b) {
  const double c = rotation_a.c, s = rotation_a.s;
  const double dx = T_w_b.x() - T_w_a.x(), dy = T_w_b.y() - T_w_a.y();
  const double x = c * dx + s * dy;
  const double y = -s * dx + c * dy;
  if (J_a) {
    // d/d(x_a, y_a, th_a); note d(x)/d(th_a) = y and d(y)/d(th_a) = -x.
    *J_a << -c, -s, y,  //
        s, -c, -x,      //
        0, 0, -1;
  }
  if (J_b) {
    *J_b << c, s, 0,  //
        -s, c, 0,     //
        0, 0, 1;
  }
  return Pose2(x, y, T_w_b.theta() - T_w_a.theta());
}

Eigen::Vector3d PoseError(const Pose2& predicted, const Pose2& measured) {
  return {predicted.x() - measured.x(), predicted.y() - measured.y(),
          AngleDifference(predicted.theta(), measured.theta())};
}

Pose2 Interpolate(const Pose2& a, const Pose2& b, double fraction) {
  return Pose2(a.x() + fraction * (b.x() - a.x()), a.y() + fraction * (b.y() - a.y()),
               a.theta() + fraction * AngleDifference(b.theta(), a.theta()));
}

}  // namespace anchormap
