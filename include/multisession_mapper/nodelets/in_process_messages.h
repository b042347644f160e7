// Messages that carry core objects between the nodelets of one manager without copying or
// serialising them (zero-copy: roscpp hands the same shared_ptr to every subscriber in the
// process). They hold shared_ptrs to immutable core objects (OdometryResult, SessionResult,
// PlaceRecognizer) that have no ROS message form. roscpp needs message traits and a serializer
// for any published type; the serializer below writes nothing, so these topics are only
// meaningful inside the nodelet manager (a subscriber in another process, e.g. `rostopic echo`,
// receives empty messages; use the regular topics odom / registered_points / submaps instead).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <std_msgs/Header.h>

#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/submap_voting.h"

namespace multisession_mapper {
namespace nodelets {

/// ScanMatching -> SubmapManager: one registered (de-skewed) scan and its odometry pose.
struct RegisteredScan {
  std_msgs::Header header;  ///< stamp = scan stamp; frame_id = sensor frame
  std::shared_ptr<const core::OdometryResult> odometry;
  /// Index of the session whose odometry registered the scan (0: the first session of this
  /// manager). ScanMatching restarts its odometry when a session has finished; SubmapManager
  /// maps only scans of its current session's odometry.
  std::uint32_t session_index = 0;
};

/// SubmapManager -> PlaceRecognition: the scan again, with the submap it went into.
struct ScanInSubmap {
  std_msgs::Header header;
  std::string session;
  std::uint32_t submap_id = 0;
  std::shared_ptr<const core::OdometryResult> odometry;
};

/// SubmapManager -> MapMerging (and PlaceRecognition, ScanMatching) at the end of a session.
struct FinishedSession {
  std::string session;
  std::uint32_t index = 0;  ///< the session's index in this manager (0: the first)
  std::string error;  ///< non-empty: the session produced nothing to merge
  std::shared_ptr<const core::SessionResult> result;
};

/// PlaceRecognition -> MapMerging at the end of a session: the per-scan queries and the voting
/// thresholds in force, so the final merge votes exactly as the live candidates did.
struct FinishedRecognition {
  std::string session;
  std::string error;
  std::shared_ptr<const core::PlaceRecognizer> recognizer;
  core::SubmapVotingConfig voting;
  double neighbour_distance_m = 30.0;
};

}  // namespace nodelets
}  // namespace multisession_mapper

// roscpp traits: name, a fixed MD5 per type (never matched against other processes) and an
// empty definition.
#define MSM_IN_PROCESS_MESSAGE(Type, md5)                                                      \
  namespace ros {                                                                              \
  namespace message_traits {                                                                   \
  template <>                                                                                  \
  struct MD5Sum<multisession_mapper::nodelets::Type> {                                         \
    static const char* value() { return md5; }                                                 \
    static const char* value(const multisession_mapper::nodelets::Type&) { return value(); }   \
  };                                                                                           \
  template <>                                                                                  \
  struct DataType<multisession_mapper::nodelets::Type> {                                       \
    static const char* value() { return "multisession_mapper/InProcess" #Type; }               \
    static const char* value(const multisession_mapper::nodelets::Type&) { return value(); }   \
  };                                                                                           \
  template <>                                                                                  \
  struct Definition<multisession_mapper::nodelets::Type> {                                     \
    static const char* value() { return "# in-process only (see in_process_messages.h)\n"; }   \
    static const char* value(const multisession_mapper::nodelets::Type&) { return value(); }   \
  };                                                                                           \
  }                                                                                            \
  namespace serialization {                                                                    \
  template <>                                                                                  \
  struct Serializer<multisession_mapper::nodelets::Type> {                                     \
    template <typename Stream>                                                                 \
    inline static void write(Stream&, const multisession_mapper::nodelets::Type&) {}           \
    template <typename Stream>                                                                 \
    inline static void read(Stream&, multisession_mapper::nodelets::Type&) {}                  \
    inline static uint32_t serializedLength(const multisession_mapper::nodelets::Type&) {      \
      return 0;                                                                                \
    }                                                                                          \
  };                                                                                           \
  }                                                                                            \
  }

MSM_IN_PROCESS_MESSAGE(RegisteredScan, "5d1e3c0a9b7f4e21a6c8d2f0b3e4a101")
MSM_IN_PROCESS_MESSAGE(ScanInSubmap, "5d1e3c0a9b7f4e21a6c8d2f0b3e4a102")
MSM_IN_PROCESS_MESSAGE(FinishedSession, "5d1e3c0a9b7f4e21a6c8d2f0b3e4a103")
MSM_IN_PROCESS_MESSAGE(FinishedRecognition, "5d1e3c0a9b7f4e21a6c8d2f0b3e4a104")
#undef MSM_IN_PROCESS_MESSAGE
