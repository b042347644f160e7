#include "multisession_mapper/ros/conversions.h"

#include <cmath>
#include <cstring>
#include <limits>


#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace conversions {
namespace {

using sensor_msgs::PointField;

const PointField* FindField(const sensor_msgs::PointCloud2& msg, const std::string& name) {
  for (const PointField& field : msg.fields) {
    if (field.name == name) return &field;
  }
  return nullptr;
}

std::size_t SizeOfDatatype(std::uint8_t datatype) {
  switch (datatype) {
    case PointField::INT8:
    case PointField::UINT8:
      return 1;
    case PointField::INT16:
    case PointField::UINT16:
      return 2;
    case PointField::INT32:
    case PointField::UINT32:
    case PointField::FLOAT32:
      return 4;
    case PointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

// Reads one value of any PointField datatype as double (memcpy: data may be unaligned).
double ReadAsDouble(const std::uint8_t* ptr, std::uint8_t datatype) {
  switch (datatype) {
    case PointField::INT8: {
      std::int8_t v;
      std::memcpy(&v, ptr, 1);
      return v;
    }
    case PointField::UINT8:
      return *ptr;
    case PointField::INT16: {
      std::int16_t v;
      std::memcpy(&v, ptr, 2);
      return v;
    }
    case PointField::UINT16: {
      std::uint16_t v;
      std::memcpy(&v, ptr, 2);
      return v;
    }
    case PointField::INT32: {
      std::int32_t v;
      std::memcpy(&v, ptr, 4);
      return v;
    }
    case PointField::UINT32: {
      std::uint32_t v;
      std::memcpy(&v, ptr, 4);
      return v;
    }
    case PointField::FLOAT32: {
      float v;
      std::memcpy(&v, ptr, 4);
      return v;
    }
    case PointField::FLOAT64: {
      double v;
      std::memcpy(&v, ptr, 8);
      return v;
    }
    default:
      return std::numeric_limits<double>::quiet_NaN();
  }
}

core::Status CheckField(const PointField* field, const sensor_msgs::PointCloud2& msg,
                        const char* name) {
  const std::size_t size = SizeOfDatatype(field->datatype);
  if (size == 0) {
    return core::Status::Error(std::string("PointCloud2 field '") + name +
                               "' has unknown datatype " + std::to_string(field->datatype));
  }
  if (field->offset + size > msg.point_step) {
    return core::Status::Error(std::string("PointCloud2 field '") + name + "' (offset " +
                               std::to_string(field->offset) + ") does not fit in point_step " +
                               std::to_string(msg.point_step));
  }
  return core::Status::Ok();
}

enum class TimeKind { kNone, kOffsetSeconds, kOffsetNanoseconds, kAbsoluteSeconds };

void AppendField(sensor_msgs::PointCloud2* msg, const std::string& name, std::uint32_t offset,
                 std::uint8_t datatype) {
  PointField field;
  field.name = name;
  field.offset = offset;
  field.datatype = datatype;
  field.count = 1;
  msg->fields.push_back(field);
}

}  // namespace

core::StatusOr<core::LidarScan> FromPointCloud2(const sensor_msgs::PointCloud2& msg) {
  if (msg.is_bigendian) {
    return core::Status::Error("PointCloud2 is big-endian; only little-endian data is supported");
  }
  const PointField* fx = FindField(msg, "x");
  const PointField* fy = FindField(msg, "y");
  const PointField* fz = FindField(msg, "z");
  if (fx == nullptr || fy == nullptr || fz == nullptr) {
    return core::Status::Error("PointCloud2 has no x/y/z fields (fields: " +
                               [&] {
                                 std::string names;
                                 for (const auto& f : msg.fields) names += f.name + " ";
                                 return names;
                               }() +
                               ")");
  }
  const std::uint64_t num_points = static_cast<std::uint64_t>(msg.width) * msg.height;
  if (num_points > 0) {
    if (msg.point_step == 0) return core::Status::Error("PointCloud2 has point_step 0");
    if (static_cast<std::uint64_t>(msg.row_step) < static_cast<std::uint64_t>(msg.width) * msg.point_step) {
      return core::Status::Error("PointCloud2 row_step " + std::to_string(msg.row_step) +
                                 " is smaller than width x point_step");
    }
    if (msg.data.size() < static_cast<std::uint64_t>(msg.row_step) * msg.height) {
      return core::Status::Error("PointCloud2 data has " + std::to_string(msg.data.size()) +
                                 " bytes, expected row_step x height = " +
                                 std::to_string(static_cast<std::uint64_t>(msg.row_step) *
                                                msg.height));
    }
  }
  for (const auto& [field, name] : {std::make_pair(fx, "x"), std::make_pair(fy, "y"),
                                    std::make_pair(fz, "z")}) {
    core::Status status = CheckField(field, msg, name);
    if (!status.ok()) return status;
  }

  const PointField* fi = FindField(msg, "intensity");
  const PointField* fr = FindField(msg, "ring");
  const PointField* ft = nullptr;
  TimeKind time_kind = TimeKind::kNone;
  if ((ft = FindField(msg, "time")) != nullptr) {
    time_kind = TimeKind::kOffsetSeconds;
  } else if ((ft = FindField(msg, "t")) != nullptr) {
    time_kind = TimeKind::kOffsetNanoseconds;
  } else if ((ft = FindField(msg, "timestamp")) != nullptr) {
    time_kind = TimeKind::kAbsoluteSeconds;
  }
  for (const auto& [field, name] :
       {std::make_pair(fi, "intensity"), std::make_pair(fr, "ring"), std::make_pair(ft, "time")}) {
    if (field == nullptr) continue;
    core::Status status = CheckField(field, msg, name);
    if (!status.ok()) return status;
  }

  core::LidarScan scan;
  scan.stamp_s = msg.header.stamp.toSec();
  scan.has_ring = fr != nullptr;
  scan.has_time = ft != nullptr;
  scan.points.reserve(num_points);
  for (std::uint32_t row = 0; row < msg.height; ++row) {
    const std::uint8_t* row_ptr = msg.data.data() + static_cast<std::size_t>(row) * msg.row_step;
    for (std::uint32_t col = 0; col < msg.width; ++col) {
      const std::uint8_t* p = row_ptr + static_cast<std::size_t>(col) * msg.point_step;
      core::LidarPoint point;
      point.position_m = Eigen::Vector3f(static_cast<float>(ReadAsDouble(p + fx->offset, fx->datatype)),
                                         static_cast<float>(ReadAsDouble(p + fy->offset, fy->datatype)),
                                         static_cast<float>(ReadAsDouble(p + fz->offset, fz->datatype)));
      if (fi != nullptr) point.intensity = static_cast<float>(ReadAsDouble(p + fi->offset, fi->datatype));
      if (fr != nullptr) {
        const double ring = ReadAsDouble(p + fr->offset, fr->datatype);
        point.ring = (ring >= 0.0 && ring <= 65535.0) ? static_cast<std::uint16_t>(ring) : 0;
      }
      if (ft != nullptr) {
        const double t = ReadAsDouble(p + ft->offset, ft->datatype);
        switch (time_kind) {
          case TimeKind::kOffsetSeconds:
            point.time_s = static_cast<float>(t);
            break;
          case TimeKind::kOffsetNanoseconds:
            point.time_s = static_cast<float>(t * 1e-9);
            break;
          case TimeKind::kAbsoluteSeconds:
            point.time_s = static_cast<float>(t - scan.stamp_s);
            break;
          case TimeKind::kNone:
            break;
        }
      }
      scan.points.push_back(point);
    }
  }
  return scan;
}

sensor_msgs::PointCloud2 ToPointCloud2(const core::LidarScan& scan, const std::string& frame_id) {
  sensor_msgs::PointCloud2 msg;
  msg.header.stamp = ToRosTime(scan.stamp_s);
  msg.header.frame_id = frame_id;
  AppendField(&msg, "x", 0, PointField::FLOAT32);
  AppendField(&msg, "y", 4, PointField::FLOAT32);
  AppendField(&msg, "z", 8, PointField::FLOAT32);
  AppendField(&msg, "intensity", 12, PointField::FLOAT32);
  AppendField(&msg, "ring", 16, PointField::UINT16);
  AppendField(&msg, "time", 20, PointField::FLOAT32);
  msg.point_step = 24;
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(scan.points.size());
  msg.row_step = msg.point_step * msg.width;
  msg.is_bigendian = false;
  msg.is_dense = true;
  msg.data.assign(static_cast<std::size_t>(msg.row_step), 0);
  std::uint8_t* out = msg.data.data();
  for (const core::LidarPoint& p : scan.points) {
    std::memcpy(out + 0, p.position_m.data(), 12);
    std::memcpy(out + 12, &p.intensity, 4);
    std::memcpy(out + 16, &p.ring, 2);
    std::memcpy(out + 20, &p.time_s, 4);
    if (!p.position_m.allFinite()) msg.is_dense = false;
    out += msg.point_step;
  }
  return msg;
}

sensor_msgs::PointCloud2 ToPointCloud2(const core::PointVector& points,
                                       const std::string& frame_id, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = frame_id;
  AppendField(&msg, "x", 0, PointField::FLOAT32);
  AppendField(&msg, "y", 4, PointField::FLOAT32);
  AppendField(&msg, "z", 8, PointField::FLOAT32);
  msg.point_step = 12;
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(points.size());
  msg.row_step = msg.point_step * msg.width;
  msg.is_bigendian = false;
  msg.is_dense = true;
  msg.data.resize(msg.row_step);
  std::uint8_t* out = msg.data.data();
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3f pf = p.cast<float>();
    std::memcpy(out, pf.data(), 12);
    if (!pf.allFinite()) msg.is_dense = false;
    out += 12;
  }
  return msg;
}

geometry_msgs::Pose ToPoseMsg(const core::Pose3& pose) {
  geometry_msgs::Pose msg;
  msg.position.x = pose.translation().x();
  msg.position.y = pose.translation().y();
  msg.position.z = pose.translation().z();
  const Eigen::Quaterniond q(pose.rotation());
  msg.orientation.x = q.x();
  msg.orientation.y = q.y();
  msg.orientation.z = q.z();
  msg.orientation.w = q.w();
  return msg;
}

core::StatusOr<core::Pose3> FromPoseMsg(const geometry_msgs::Pose& msg) {
  const Eigen::Vector3d t(msg.position.x, msg.position.y, msg.position.z);
  const Eigen::Quaterniond q(msg.orientation.w, msg.orientation.x, msg.orientation.y,
                             msg.orientation.z);
  if (!t.allFinite() || !q.coeffs().allFinite()) {
    return core::Status::Error("geometry_msgs/Pose has non-finite values");
  }
  if (q.norm() < 1e-6) return core::Status::Error("geometry_msgs/Pose has a zero quaternion");
  return core::se3::FromTranslationQuaternion(t, q);
}

ros::Time ToRosTime(double stamp_s) {
  if (!std::isfinite(stamp_s) || stamp_s < 0.0) return ros::Time(0);
  ros::Time t;
  t.fromSec(stamp_s);
  return t;
}

double ToSeconds(const ros::Time& stamp) { return stamp.toSec(); }

std::uint8_t ToLoopStatusMsg(core::LoopStatus status) {
  switch (status) {
    case core::LoopStatus::kCandidate: return multisession_mapper::LoopCandidate::CANDIDATE;
    case core::LoopStatus::kAccepted: return multisession_mapper::LoopCandidate::ACCEPTED;
    case core::LoopStatus::kRejected: return multisession_mapper::LoopCandidate::REJECTED;
    case core::LoopStatus::kUndefined: break;
  }
  return multisession_mapper::LoopCandidate::UNDEFINED;
}

multisession_mapper::LoopCandidate ToLoopCandidateMsg(const core::LoopRecord& record) {
  auto finite_or_zero = [](double v) { return std::isfinite(v) ? static_cast<float>(v) : 0.0f; };
  multisession_mapper::LoopCandidate msg;
  msg.current_session = record.current_session;
  msg.current_submap = record.current_submap;
  msg.history_session = record.history_session;
  msg.history_submap = record.history_submap >= 0 ? static_cast<std::uint32_t>(record.history_submap) : 0u;
  msg.status = ToLoopStatusMsg(record.status);
  msg.vote_proportion = finite_or_zero(record.vote_proportion);
  msg.overlap_ratio = finite_or_zero(record.overlap_ratio);
  msg.relative_pose = ToPoseMsg(record.has_pose ? record.T_history_current : core::Pose3::Identity());
  msg.reason = record.reason;
  return msg;
}

}  // namespace conversions
}  // namespace multisession_mapper
