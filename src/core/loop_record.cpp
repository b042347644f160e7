#include "multisession_mapper/core/loop_record.h"

#include <iomanip>
#include <sstream>

namespace multisession_mapper {
namespace core {

const char* LoopKindName(LoopKind kind) {
  switch (kind) {
    case LoopKind::kIntra:
      return "intra";
    case LoopKind::kInter:
      return "inter";
    case LoopKind::kInterProximity:
      return "inter_proximity";
    case LoopKind::kInterSequence:
      return "inter_sequence";
  }
  return "unknown";
}

const char* LoopStatusName(LoopStatus status) {
  switch (status) {
    case LoopStatus::kCandidate:
      return "candidate";
    case LoopStatus::kAccepted:
      return "accepted";
    case LoopStatus::kRejected:
      return "rejected";
    case LoopStatus::kUndefined:
      return "undefined";
  }
  return "unknown";
}

std::string LoopRecordsToCsv(const LoopRecords& records) {
  std::ostringstream out;
  out << "kind,current_session,current_submap,history_session,history_submap,status,"
         "vote_proportion,overlap_ratio,structure_overlap_ratio,tx,ty,tz,qx,qy,qz,qw,reason\n";
  out << std::setprecision(9);
  for (const LoopRecord& r : records) {
    out << LoopKindName(r.kind) << ',' << r.current_session << ',' << r.current_submap << ','
        << r.history_session << ',';
    if (r.history_submap >= 0) out << r.history_submap;
    out << ',' << LoopStatusName(r.status) << ',' << r.vote_proportion << ',' << r.overlap_ratio
        << ',' << r.structure_overlap_ratio;
    if (r.has_pose) {
      const Eigen::Quaterniond q(r.T_history_current.rotation());
      const Eigen::Vector3d& t = r.T_history_current.translation();
      out << ',' << t.x() << ',' << t.y() << ',' << t.z() << ',' << q.x() << ',' << q.y() << ','
          << q.z() << ',' << q.w();
    } else {
      out << ",,,,,,,";
    }
    std::string reason = r.reason;
    for (char& c : reason) {
      if (c == ',' || c == '\n' || c == '\r') c = ';';
    }
    out << ',' << reason << '\n';
  }
  return out.str();
}

}  // namespace core
}  // namespace multisession_mapper
