#include "multisession_mapper/core/frame_anchor.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

using Submaps = std::vector<Submap, Eigen::aligned_allocator<Submap>>;

// A courtyard in the session frame: sloped ground, walls facing four ways and a few posts, so
// that every degree of freedom of a registration is constrained.
PointVector Courtyard() {
  PointVector points;
  for (double x = -45.0; x <= 45.0; x += 0.25) {
    for (double y = -30.0; y <= 30.0; y += 0.25) points.emplace_back(x, y, 0.02 * x - 1.5);
  }
  for (double h = -1.5; h <= 5.0; h += 0.2) {
    for (double t = -45.0; t <= 45.0; t += 0.2) {
      points.emplace_back(t, 30.0, h);
      points.emplace_back(t, -30.0 + 0.1 * std::sin(t), h);
    }
    for (double t = -30.0; t <= 30.0; t += 0.2) {
      points.emplace_back(45.0, t, h);
      points.emplace_back(-45.0, t, h);
    }
    for (double a = 0.0; a < 2.0 * M_PI; a += 0.2) {
      for (const Eigen::Vector2d& c : {Eigen::Vector2d(8.0, 5.0), Eigen::Vector2d(-12.0, -9.0),
                                       Eigen::Vector2d(20.0, -14.0)}) {
        points.emplace_back(c.x() + 0.4 * std::cos(a), c.y() + 0.4 * std::sin(a), h);
      }
    }
  }
  return points;
}

Submap MakeSubmap(std::uint32_t id, const Pose3& T_session_submap, const PointVector& session_points,
                  double keep_within_m) {
  Submap s;
  s.session = "s00";
  s.id = id;
  s.T_map_submap = T_session_submap;
  s.scans.emplace_back();
  const Pose3 T_submap_session = T_session_submap.inverse();
  for (const Eigen::Vector3d& p : session_points) {
    if ((p - T_session_submap.translation()).norm() <= keep_within_m) {
      s.points.push_back(T_submap_session * p);
    }
  }
  return s;
}

TEST(FrameAnchor, RecoversTheFirstScanPoseFromTheOtherSubmaps) {
  const PointVector world = Courtyard();
  // The first scan's true pose in the current session frame: the graph left it tilted.
  const Pose3 truth = se3::FromXyzRpy(0.05, -0.08, 0.03, 0.004, -0.006, 0.003);
  Submaps submaps;
  // Submap 0 holds the scan at the identity (its own points would pin the result there).
  Submap first = MakeSubmap(0, Pose3::Identity(), world, 30.0);
  submaps.push_back(first);
  submaps.push_back(MakeSubmap(1, se3::FromXyzRpy(20.0, 2.0, 0.4, 0.0, 0.0, 0.3), world, 40.0));
  submaps.push_back(MakeSubmap(2, se3::FromXyzRpy(-20.0, -3.0, -0.4, 0.0, 0.0, -2.0), world, 40.0));
  submaps.push_back(MakeSubmap(3, se3::FromXyzRpy(200.0, 0.0, 0.0, 0.0, 0.0, 0.0), world, 40.0));
  PointVector scan;
  const Pose3 T_scan_session = truth.inverse();
  for (const Eigen::Vector3d& p : world) {
    if ((p - truth.translation()).norm() <= 35.0) scan.push_back(T_scan_session * p);
  }
  const FrameAnchorResult r = EstimateFirstScanPose(scan, submaps, 0, FrameAnchorConfig());
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_EQ(r.reference_submaps, 2u) << "submap 0 and the far submap 3 are left out";
  const Pose3 error = se3::Between(truth, r.T_session_scan);
  EXPECT_LT(se3::TranslationNorm(error), 0.01);
  EXPECT_LT(se3::RotationAngleRad(error), 0.02 * M_PI / 180.0);
  EXPECT_GT(r.correction_rad, 0.005);

  // A correction beyond the bounds is reported, not applied.
  FrameAnchorConfig tight;
  tight.max_correction_rad = 0.001;
  const FrameAnchorResult refused = EstimateFirstScanPose(scan, submaps, 0, tight);
  EXPECT_FALSE(refused.accepted);
  EXPECT_NE(refused.reason.find("beyond the bounds"), std::string::npos) << refused.reason;

  // A correction within the registration's error keeps the graph's frame.
  FrameAnchorConfig coarse;
  coarse.min_correction_rad = 0.019;
  const FrameAnchorResult small_one = EstimateFirstScanPose(scan, submaps, 0, coarse);
  EXPECT_FALSE(small_one.accepted);
  EXPECT_NE(small_one.reason.find("min_correction_rad"), std::string::npos) << small_one.reason;

  // Without another submap near the first scan there is nothing to anchor on.
  const Submaps alone = {first, submaps[3]};
  const FrameAnchorResult none = EstimateFirstScanPose(scan, alone, 0, FrameAnchorConfig());
  EXPECT_FALSE(none.accepted);
  EXPECT_NE(none.reason.find("no other submap"), std::string::npos) << none.reason;
}

TEST(FrameAnchor, ReanchorMovesTheSessionRigidlyAndTheFirstScanToTheIdentity) {
  PoseGraph graph;
  Submaps submaps;
  for (std::uint32_t id = 0; id < 3; ++id) {
    Submap s;
    s.id = id;
    s.T_map_submap = id == 0 ? Pose3::Identity() : se3::FromXyzRpy(20.0 * id, 1.0, 0.2, 0.01, 0.0, 0.1 * id);
    s.scans.resize(2);
    s.scans[1].T_submap_sensor = se3::FromXyzRpy(1.0, 0.0, 0.0, 0.0, 0.0, 0.01);
    graph.SetNodePose(id, s.T_map_submap);
    submaps.push_back(s);
  }
  graph.SetUp(Eigen::Vector3d(0.01, -0.02, 1.0));
  const Eigen::Vector3d up_before = graph.up();
  const Pose3 between_before = se3::Between(submaps[1].T_map_submap, submaps[2].T_map_submap);
  const Pose3 T_session_scan = se3::FromXyzRpy(0.1, -0.05, 0.02, 0.003, -0.004, 0.002);
  Reanchor(T_session_scan, 0, &graph, &submaps);
  // The first scan is the identity of the new frame.
  const Pose3 first = submaps[0].T_map_submap * submaps[0].scans[0].T_submap_sensor;
  EXPECT_TRUE(first.isApprox(Pose3::Identity(), 1e-12));
  // Everything moved by the same rigid transform: relative poses, graph and submaps agree.
  EXPECT_TRUE(se3::Between(submaps[1].T_map_submap, submaps[2].T_map_submap)
                  .isApprox(between_before, 1e-12));
  for (const Submap& s : submaps) EXPECT_TRUE(graph.NodePose(s.id).isApprox(s.T_map_submap, 1e-12));
  EXPECT_TRUE(submaps[0].T_map_submap.isApprox(T_session_scan.inverse(), 1e-12));
  EXPECT_TRUE(graph.up().isApprox(T_session_scan.linear().transpose() * up_before, 1e-12));
  // Other scan records keep their poses in their submaps.
  EXPECT_TRUE(submaps[1].scans[0].T_submap_sensor.isApprox(Pose3::Identity(), 1e-12));
}

TEST(FrameAnchorConfig, InvalidValuesAreRefused) {
  FrameAnchorConfig config;
  EXPECT_TRUE(config.Validate().ok()) << config.Validate().message();
  config.scans = 0;
  EXPECT_FALSE(config.Validate().ok());
  config = FrameAnchorConfig();
  config.max_correction_rad = 0.0;
  EXPECT_FALSE(config.Validate().ok());
  config = FrameAnchorConfig();
  config.min_correction_rad = config.max_correction_rad;
  EXPECT_FALSE(config.Validate().ok());
  config = FrameAnchorConfig();
  config.reference_radius_m = -1.0;
  EXPECT_FALSE(config.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
