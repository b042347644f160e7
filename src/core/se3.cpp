#include "multisession_mapper/core/se3.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace multisession_mapper {
namespace core {
namespace se3 {

Pose3 FromTranslationQuaternion(const Eigen::Vector3d& t_m, const Eigen::Quaterniond& q) {
  Pose3 pose = Pose3::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = t_m;
  return pose;
}

Pose3 FromXyzRpy(double x_m, double y_m, double z_m, double roll_rad, double pitch_rad,
                 double yaw_rad) {
  const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX());
  return FromTranslationQuaternion(Eigen::Vector3d(x_m, y_m, z_m), q);
}

Pose3 Exp(const Vector6d& xi) {
  Pose3 pose = Pose3::Identity();
  const Eigen::Vector3d w = xi.tail<3>();
  const double angle = w.norm();
  if (angle > 1e-12) {
    pose.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  }
  pose.translation() = xi.head<3>();
  return pose;
}

Vector6d Log(const Pose3& pose) {
  Vector6d xi;
  const Eigen::AngleAxisd aa(pose.rotation());
  xi.head<3>() = pose.translation();
  xi.tail<3>() = aa.axis() * aa.angle();
  if (!xi.tail<3>().allFinite()) xi.tail<3>().setZero();
  return xi;
}

Pose3 Interpolate(const Pose3& a, const Pose3& b, double alpha) {
  const Eigen::Quaterniond qa(a.rotation());
  const Eigen::Quaterniond qb(b.rotation());
  Pose3 out = Pose3::Identity();
  if (alpha >= 0.0 && alpha <= 1.0) {
    out.linear() = qa.slerp(alpha, qb).toRotationMatrix();
  } else {
    // Extrapolation: scale the relative rotation vector.
    const Eigen::AngleAxisd rel(qa.inverse() * qb);
    out.linear() =
        (qa * Eigen::Quaterniond(Eigen::AngleAxisd(rel.angle() * alpha, rel.axis())))
            .toRotationMatrix();
  }
  out.translation() = (1.0 - alpha) * a.translation() + alpha * b.translation();
  return out;
}

double RotationAngleRad(const Pose3& pose) {
  const double c = std::clamp((pose.rotation().trace() - 1.0) * 0.5, -1.0, 1.0);
  return std::acos(c);
}

double TranslationNorm(const Pose3& pose) { return pose.translation().norm(); }

Pose3 Between(const Pose3& a, const Pose3& b) { return a.inverse() * b; }

Pose3 Normalized(const Pose3& pose) {
  Pose3 out = pose;
  out.linear() = Eigen::Quaterniond(pose.rotation()).normalized().toRotationMatrix();
  return out;
}

bool IsValid(const Pose3& pose, double tolerance) {
  if (!pose.matrix().allFinite()) return false;
  const Eigen::Matrix3d r = pose.linear();
  if (!(r.transpose() * r).isApprox(Eigen::Matrix3d::Identity(), tolerance)) return false;
  return std::abs(r.determinant() - 1.0) < tolerance * 10.0;
}

namespace {

// Heading of a rotation: the angle of its x axis projected on the horizontal plane; nullopt
// when that axis is (nearly) vertical.
std::optional<double> HeadingOf(const Eigen::Matrix3d& R) {
  if (std::hypot(R(0, 0), R(1, 0)) < 1e-6) return std::nullopt;
  return std::atan2(R(1, 0), R(0, 0));
}

}  // namespace

Pose3 WithTiltAndHeightOf(const Pose3& pose, const Pose3& other) {
  const std::optional<double> yaw = HeadingOf(pose.linear());
  const std::optional<double> other_yaw = HeadingOf(other.linear());
  if (!yaw || !other_yaw) return pose;  // no heading to keep (never on a ground robot)
  // `other` turned about the vertical by the heading difference: a rotation about the world z
  // axis in front keeps its body roll and pitch.
  Pose3 out = pose;
  out.linear() = Eigen::AngleAxisd(*yaw - *other_yaw, Eigen::Vector3d::UnitZ()) * other.linear();
  out.translation().z() = other.translation().z();
  return Normalized(out);
}

}  // namespace se3
}  // namespace core
}  // namespace multisession_mapper
