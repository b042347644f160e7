// SE(3) helpers: conversions between poses and the minimal (translation, rotation-vector)
// parameterisation, interpolation for de-skewing, and pose error measures used by validation
// thresholds and the evaluator.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {
namespace se3 {

using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Pose from translation [m] and unit quaternion (normalised here).
Pose3 FromTranslationQuaternion(const Eigen::Vector3d& t_m, const Eigen::Quaterniond& q);

/// Pose from translation [m] and roll/pitch/yaw [rad] (R = Rz(yaw) Ry(pitch) Rx(roll)).
Pose3 FromXyzRpy(double x_m, double y_m, double z_m, double roll_rad, double pitch_rad,
                 double yaw_rad);

/// Exponential map: tangent vector (translation [m], rotation vector [rad]) to a pose.
/// Uses the decoupled (SO(3) x R3) form, which is what constant-velocity de-skewing needs.
Pose3 Exp(const Vector6d& xi);

/// Inverse of Exp.
Vector6d Log(const Pose3& pose);

/// Pose at fraction `alpha` in [0, 1] of the way from `a` to `b` (slerp on rotation,
/// linear on translation). alpha outside [0, 1] extrapolates.
Pose3 Interpolate(const Pose3& a, const Pose3& b, double alpha);

/// Rotation angle of a pose [rad], in [0, pi].
double RotationAngleRad(const Pose3& pose);

/// Translation norm of a pose [m].
double TranslationNorm(const Pose3& pose);

/// The relative pose a^-1 * b.
Pose3 Between(const Pose3& a, const Pose3& b);

/// Re-orthonormalises the rotation part (drift after many compositions).
Pose3 Normalized(const Pose3& pose);

/// True when every coefficient is finite and the rotation is orthonormal within `tolerance`.
bool IsValid(const Pose3& pose, double tolerance = 1e-6);

/// `other`'s roll, pitch and height with `pose`'s heading and horizontal position (heading:
/// the horizontal direction of the x axis). `pose` unchanged when either x axis is vertical
/// (no heading to keep).
Pose3 WithTiltAndHeightOf(const Pose3& pose, const Pose3& other);

}  // namespace se3
}  // namespace core
}  // namespace multisession_mapper
