#include "multisession_mapper/core/pose_graph.h"

#include <cmath>
#include <functional>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

// Ground truth: 40 submap origins on a loop of radius 30 m with gentle height and pitch changes.
std::vector<Pose3, Eigen::aligned_allocator<Pose3>> GroundTruth() {
  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> poses;
  for (int i = 0; i < 40; ++i) {
    const double a = 2.0 * M_PI * i / 40.0;
    poses.push_back(se3::FromXyzRpy(30.0 * std::cos(a), 30.0 * std::sin(a), std::sin(a) * 2.0,
                                    0.02 * std::sin(3 * a), 0.03 * std::cos(a), a + M_PI / 2));
  }
  return poses;
}

Information6 Info(double sigma_t_m, double sigma_r_rad) {
  Information6 info = Information6::Zero();
  info.diagonal() << Eigen::Vector3d::Constant(1.0 / (sigma_t_m * sigma_t_m)),
      Eigen::Vector3d::Constant(1.0 / (sigma_r_rad * sigma_r_rad));
  return info;
}

Pose3 Perturb(const Pose3& pose, std::mt19937* rng, double sigma_t, double sigma_r) {
  std::normal_distribution<double> n(0.0, 1.0);
  se3::Vector6d xi;
  xi << sigma_t * n(*rng), sigma_t * n(*rng), sigma_t * n(*rng), sigma_r * n(*rng),
      sigma_r * n(*rng), sigma_r * n(*rng);
  return pose * se3::Exp(xi);
}

// A chain of odometry edges from node 0 (fixed at truth[0]); `measure(i)` is the measured
// motion from node i - 1 to node i. The initial estimate is the dead-reckoned chain.
PoseGraph OdometryChain(const std::vector<Pose3, Eigen::aligned_allocator<Pose3>>& truth,
                        const std::function<Pose3(int)>& measure, const Information6& info) {
  PoseGraph graph;
  Pose3 estimate = truth[0];
  graph.SetNodePose(0, estimate);
  graph.SetFixed(0, true);
  for (int i = 1; i < static_cast<int>(truth.size()); ++i) {
    const Pose3 measured = measure(i);
    estimate = estimate * measured;
    graph.SetNodePose(i, estimate);
    PoseGraphEdge e;
    e.from = i - 1;
    e.to = i;
    e.T_from_to = measured;
    e.information = info;
    EXPECT_TRUE(graph.AddEdge(e).ok());
  }
  return graph;
}

// Builds a graph whose initial estimate is dead-reckoned noisy odometry (it drifts), with
// accurate loops every fifth node (as from revisits) and from the end back to the start.
PoseGraph BuildGraph(std::mt19937* rng, bool with_loops) {
  const auto truth = GroundTruth();
  PoseGraph graph = OdometryChain(
      truth,
      [&](int i) { return Perturb(se3::Between(truth[i - 1], truth[i]), rng, 0.05, 0.01); },
      Info(0.05, 0.01));
  if (with_loops) {
    std::vector<std::pair<int, int>> loops = {{39, 0}};
    for (int i = 0; i < 40; i += 5) loops.emplace_back(i, (i + 10) % 40);
    for (const auto& [a, b] : loops) {
      PoseGraphEdge e;
      e.from = a;
      e.to = b;
      e.T_from_to = Perturb(se3::Between(truth[a], truth[b]), rng, 0.01, 0.002);
      e.information = Info(0.02, 0.004);
      e.kind = EdgeKind::kIntraLoop;
      EXPECT_TRUE(graph.AddEdge(e).ok());
    }
  }
  return graph;
}

// The plain least-squares optimum (no kernel, no gate) of a graph: with no outliers the robust
// solve must land on it.
PoseGraph LeastSquaresSolution(PoseGraph graph) {
  PoseGraphConfig plain;
  plain.loop_kernel_scale = plain.loop_kernel_initial_scale = 1e9;
  plain.loop_outlier_chi2 = 0.0;
  graph.set_config(plain);
  EXPECT_TRUE(graph.Optimize().ok());
  return graph;
}

double MaxDifference(const PoseGraph& a, const PoseGraph& b) {
  double worst = 0.0;
  for (const auto& [id, pose] : a.nodes()) {
    worst = std::max(worst, (pose.translation() - b.NodePose(id).translation()).norm());
  }
  return worst;
}

double MaxTranslationError(const PoseGraph& graph) {
  const auto truth = GroundTruth();
  double worst = 0.0;
  for (int i = 0; i < 40; ++i) {
    worst = std::max(worst, (graph.NodePose(i).translation() - truth[i].translation()).norm());
  }
  return worst;
}

class PoseGraphSeeds : public ::testing::TestWithParam<int> {};

TEST_P(PoseGraphSeeds, LoopsRemoveOdometryDrift) {
  std::mt19937 rng(GetParam());
  PoseGraph graph = BuildGraph(&rng, true);
  const PoseGraph optimum = LeastSquaresSolution(graph);
  const double before = MaxTranslationError(graph);
  StatusOr<PoseGraphSummary> summary = graph.Optimize();
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  const double after = MaxTranslationError(graph);
  EXPECT_GT(before, 1.0) << "the test needs visible drift to be meaningful";
  EXPECT_LT(after, 0.4);
  EXPECT_LT(after, before / 5.0);
  // No outliers: the robust solve reaches the least-squares optimum and rejects nothing.
  EXPECT_LT(MaxDifference(graph, optimum), 0.03);
  EXPECT_TRUE(summary.value().rejected_edges.empty());
  EXPECT_TRUE(graph.NodePose(0).isApprox(GroundTruth()[0], 1e-12)) << "fixed node moved";
}

INSTANTIATE_TEST_SUITE_P(Seeds, PoseGraphSeeds, ::testing::Values(3, 5, 11, 17));

TEST(PoseGraph, WrongLoopIsRejectedAndDoesNotWreckTheGraph) {
  std::mt19937 rng(3);
  PoseGraph graph = BuildGraph(&rng, true);
  const PoseGraph optimum_without_wrong_loop = LeastSquaresSolution(graph);
  // An aliased place: claims node 25 sits 8 m beside node 5 with a quarter turn.
  PoseGraphEdge wrong;
  wrong.from = 5;
  wrong.to = 25;
  wrong.T_from_to = se3::FromXyzRpy(8.0, 0.0, 0.0, 0.0, 0.0, M_PI / 2);
  wrong.information = Info(0.02, 0.004);
  wrong.kind = EdgeKind::kInterLoop;
  StatusOr<std::size_t> index = graph.AddEdge(wrong);
  ASSERT_TRUE(index.ok());
  StatusOr<PoseGraphSummary> summary = graph.Optimize();
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  EXPECT_LT(MaxDifference(graph, optimum_without_wrong_loop), 0.03);
  ASSERT_EQ(summary.value().rejected_edges.size(), 1u);
  EXPECT_EQ(summary.value().rejected_edges[0], index.value());
  EXPECT_FALSE(graph.edges()[index.value()].enabled);
}

TEST(PoseGraph, WithoutLoopsOdometryIsKept) {
  std::mt19937 rng(5);
  PoseGraph graph = BuildGraph(&rng, false);
  const Pose3 last_before = graph.NodePose(39);
  ASSERT_TRUE(graph.Optimize().ok());
  // Only odometry: the dead-reckoned chain is already optimal.
  EXPECT_TRUE(graph.NodePose(39).isApprox(last_before, 1e-6));
}

TEST(PoseGraph, RejectsBadEdgesAndMissingGauge) {
  PoseGraph graph;
  graph.SetNodePose(0, Pose3::Identity());
  graph.SetNodePose(1, se3::FromXyzRpy(1, 0, 0, 0, 0, 0));
  PoseGraphEdge e;
  e.from = 0;
  e.to = 7;
  EXPECT_FALSE(graph.AddEdge(e).ok()) << "missing node";
  e.to = 1;
  e.information = Information6::Zero();
  EXPECT_FALSE(graph.AddEdge(e).ok()) << "singular information";
  e.information = Information6::Identity();
  e.information(0, 1) = 5.0;  // not symmetric
  EXPECT_FALSE(graph.AddEdge(e).ok());
  e.information = Information6::Identity();
  ASSERT_TRUE(graph.AddEdge(e).ok());
  StatusOr<PoseGraphSummary> no_gauge = graph.Optimize();
  ASSERT_FALSE(no_gauge.ok());
  EXPECT_NE(no_gauge.status().message().find("fixed"), std::string::npos);
}

TEST(PoseGraph, G2oRoundTripKeepsEverything) {
  std::mt19937 rng(11);
  PoseGraph graph = BuildGraph(&rng, true);
  PoseGraphEdge wrong;
  wrong.from = 5;
  wrong.to = 25;
  wrong.T_from_to = se3::FromXyzRpy(8.0, 0.0, 0.0, 0.0, 0.0, 1.0);
  wrong.information = Info(0.1, 0.02);
  wrong.information(0, 4) = wrong.information(4, 0) = 1.0;  // a cross term survives too
  wrong.kind = EdgeKind::kInterLoop;
  ASSERT_TRUE(graph.AddEdge(wrong).ok());
  Eigen::Matrix3d prior = Eigen::Matrix3d::Identity() * 4e4;
  prior(0, 1) = prior(1, 0) = 1e3;
  prior(2, 2) = 0.0;
  for (NodeId id : {3, 8, 30}) ASSERT_TRUE(graph.SetVerticalPrior(id, prior).ok());
  ASSERT_TRUE(graph.Optimize().ok());

  std::stringstream text;
  ASSERT_TRUE(graph.WriteG2o(text).ok());
  StatusOr<PoseGraph> back = PoseGraph::ReadG2o(text, "graph.g2o");
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back.value().nodes().size(), graph.nodes().size());
  ASSERT_EQ(back.value().edges().size(), graph.edges().size());
  EXPECT_EQ(back.value().fixed(), graph.fixed());
  for (const auto& [id, pose] : graph.nodes()) {
    EXPECT_TRUE(back.value().NodePose(id).isApprox(pose, 1e-9)) << "node " << id;
  }
  for (std::size_t i = 0; i < graph.edges().size(); ++i) {
    const PoseGraphEdge& a = graph.edges()[i];
    const PoseGraphEdge& b = back.value().edges()[i];
    EXPECT_EQ(a.from, b.from);
    EXPECT_EQ(a.to, b.to);
    EXPECT_EQ(a.kind, b.kind);
    EXPECT_EQ(a.enabled, b.enabled);
    EXPECT_TRUE(a.T_from_to.isApprox(b.T_from_to, 1e-9));
    EXPECT_TRUE(a.information.isApprox(b.information, 1e-9));
  }
  ASSERT_EQ(back.value().vertical_priors().size(), 3u);
  for (const auto& [id, information] : graph.vertical_priors()) {
    ASSERT_EQ(back.value().vertical_priors().count(id), 1u) << "node " << id;
    EXPECT_TRUE(back.value().vertical_priors().at(id).isApprox(information, 1e-9));
  }
  EXPECT_TRUE(back.value().up().isApprox(graph.up(), 1e-9));
}

// Route of 30 submaps over 20 m each across rolling terrain (pitch and roll of a few deg).
std::vector<Pose3, Eigen::aligned_allocator<Pose3>> HillyRoute() {
  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> poses;
  double z = 0.0;
  for (int i = 0; i < 30; ++i) {
    const double pitch = 0.05 * std::sin(0.4 * i), roll = 0.03 * std::cos(0.3 * i);
    poses.push_back(se3::FromXyzRpy(20.0 * i, 2.0 * std::sin(0.2 * i), z, roll, pitch, 0.1 * std::sin(0.2 * i)));
    z -= 20.0 * std::sin(pitch);
  }
  return poses;
}

// Tilt error of a node: angle between the up direction it sees and the true one [deg].
double TiltErrorDeg(const PoseGraph& graph, NodeId id, const Pose3& truth) {
  const Eigen::Vector3d seen = graph.NodePose(id).rotation().transpose() * graph.up();
  const Eigen::Vector3d real = truth.rotation().transpose() * Eigen::Vector3d::UnitZ();
  return std::acos(std::min(1.0, seen.dot(real))) * 180.0 / M_PI;
}

TEST(PoseGraph, VerticalPriorsStopTheTiltDriftOfOdometry) {
  const auto truth = HillyRoute();
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  // Odometry that pitches down 0.15 deg more per link than the truth (LiDAR-only drift).
  auto build = [&](bool with_priors) {
    PoseGraph graph = OdometryChain(
        truth,
        [&](int i) {
          return se3::Between(truth[i - 1], truth[i]) *
                 se3::FromXyzRpy(0, 0, 0, 0, 0.15 * M_PI / 180.0, 0);
        },
        Info(0.15, 0.005));
    for (int i = 0; i < 30 && with_priors; ++i) {
      // Walls seen from node i: their normals are horizontal in the world; the estimate of
      // up they give is 0.25 deg off in a random direction.
      const Eigen::Matrix3d R = truth[i].rotation().transpose();
      const Eigen::Vector3d error = 0.25 * M_PI / 180.0 * Eigen::Vector3d(n(rng), n(rng), 0.0).normalized();
      const Eigen::Vector3d up = (R * (Eigen::Vector3d::UnitZ() + error)).normalized();
      const Eigen::Matrix3d information =
          (Eigen::Matrix3d::Identity() - up * up.transpose()) / (0.005 * 0.005);
      EXPECT_TRUE(graph.SetVerticalPrior(i, information).ok());
    }
    EXPECT_TRUE(graph.Optimize().ok());
    return graph;
  };
  const PoseGraph drifting = build(false);
  const PoseGraph levelled = build(true);
  double worst_drifting = 0.0, worst_levelled = 0.0;
  for (int i = 0; i < 30; ++i) {
    worst_drifting = std::max(worst_drifting, TiltErrorDeg(drifting, i, truth[i]));
    worst_levelled = std::max(worst_levelled, TiltErrorDeg(levelled, i, truth[i]));
  }
  EXPECT_GT(worst_drifting, 4.0);  // 29 x 0.15 deg
  EXPECT_LT(worst_levelled, 0.5);
  const double height_drifting = std::abs(drifting.NodePose(29).translation().z() - truth[29].translation().z());
  const double height_levelled = std::abs(levelled.NodePose(29).translation().z() - truth[29].translation().z());
  EXPECT_GT(height_drifting, 10.0);
  EXPECT_LT(height_levelled, 0.2 * height_drifting);
  // The common up direction is the fixed frame's z within the priors' noise.
  EXPECT_LT(std::acos(std::min(1.0, levelled.up().z())) * 180.0 / M_PI, 0.3);
}

TEST(PoseGraph, VerticalPriorsAreValidated) {
  PoseGraph graph;
  graph.SetNodePose(0, Pose3::Identity());
  EXPECT_FALSE(graph.SetVerticalPrior(5, Eigen::Matrix3d::Identity()).ok()) << "missing node";
  EXPECT_FALSE(graph.SetVerticalPrior(0, -Eigen::Matrix3d::Identity()).ok()) << "negative";
  Eigen::Matrix3d asymmetric = Eigen::Matrix3d::Identity();
  asymmetric(0, 2) = 3.0;
  EXPECT_FALSE(graph.SetVerticalPrior(0, asymmetric).ok());
  ASSERT_TRUE(graph.SetVerticalPrior(0, Eigen::Matrix3d::Identity()).ok());
  EXPECT_EQ(graph.vertical_priors().size(), 1u);
  ASSERT_TRUE(graph.SetVerticalPrior(0, Eigen::Matrix3d::Zero()).ok());
  EXPECT_TRUE(graph.vertical_priors().empty()) << "a zero matrix removes the prior";
}

TEST(PoseGraph, G2oErrorsNameTheLine) {
  std::istringstream bad("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 0 1 2\n");
  StatusOr<PoseGraph> graph = PoseGraph::ReadG2o(bad, "graph.g2o");
  ASSERT_FALSE(graph.ok());
  EXPECT_NE(graph.status().message().find("graph.g2o:2"), std::string::npos)
      << graph.status().message();
  std::istringstream unknown("VERTEX_XY 0 1 2\n");
  EXPECT_FALSE(PoseGraph::ReadG2o(unknown, "g").ok());
  std::istringstream dup("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n");
  EXPECT_FALSE(PoseGraph::ReadG2o(dup, "g").ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
