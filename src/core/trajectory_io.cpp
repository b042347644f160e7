#include "multisession_mapper/core/trajectory_io.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {

Status WriteTum(std::ostream& out, const Trajectory& trajectory) {
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& sp : trajectory) {
    if (!se3::IsValid(sp.pose, 1e-4) || !std::isfinite(sp.stamp_s)) {
      return Status::Error("WriteTum: invalid pose at stamp " + std::to_string(sp.stamp_s));
    }
    const Eigen::Quaterniond q(sp.pose.rotation());
    const Eigen::Vector3d& t = sp.pose.translation();
    out << std::fixed << std::setprecision(9) << sp.stamp_s << std::setprecision(6) << ' '
        << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << std::setprecision(9) << q.x() << ' '
        << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  if (!out) return Status::Error("WriteTum: stream error");
  return Status::Ok();
}

Status WriteTumFile(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out(path);
  if (!out) return Status::Error("cannot open '" + path + "' for writing");
  Status status = WriteTum(out, trajectory);
  out.close();
  if (!status.ok()) return Status::Error(path + ": " + status.message());
  if (!out) return Status::Error("error while writing '" + path + "'");
  return Status::Ok();
}

StatusOr<Trajectory> ReadTum(std::istream& in, const std::string& source_name) {
  Trajectory trajectory;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    double v[8];
    for (double& value : v) {
      if (!(fields >> value)) {
        return Status::Error(source_name + ":" + std::to_string(line_number) +
                             ": expected 8 numbers 'timestamp tx ty tz qx qy qz qw'");
      }
      if (!std::isfinite(value)) {
        return Status::Error(source_name + ":" + std::to_string(line_number) +
                             ": non-finite value");
      }
    }
    std::string extra;
    if (fields >> extra) {
      return Status::Error(source_name + ":" + std::to_string(line_number) +
                           ": more than 8 values on the line");
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-6) {
      return Status::Error(source_name + ":" + std::to_string(line_number) +
                           ": zero quaternion");
    }
    if (!trajectory.empty() && v[0] <= trajectory.back().stamp_s) {
      return Status::Error(source_name + ":" + std::to_string(line_number) +
                           ": timestamps must increase strictly");
    }
    StampedPose sp;
    sp.stamp_s = v[0];
    sp.pose = se3::FromTranslationQuaternion(Eigen::Vector3d(v[1], v[2], v[3]), q);
    trajectory.push_back(sp);
  }
  return trajectory;
}

StatusOr<Trajectory> ReadTumFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::Error("cannot open trajectory file '" + path + "'");
  return ReadTum(in, path);
}

}  // namespace core
}  // namespace multisession_mapper
