// Pose graph of submap origins (reference paper eq. 1 and 3): nodes are submap poses in the
// map frame, edges are relative-pose measurements (odometry between successive submaps,
// intra- and inter-session loops) with information matrices. Solved with Ceres
// (Levenberg-Marquardt), rotations on the quaternion manifold, a robust kernel on loop edges.
// The kernel scale is annealed from wide to narrow (graduated non-convexity), and loop edges
// whose whitened error stays above a chi-square gate are then switched off one at a time with a
// new solve after each, so a single wrong loop cannot wreck the graph.
// Optional vertical priors (see vertical_structure.h): the graph then also estimates the up
// direction of the fixed frame and pulls each such node's tilt towards it, which stops the
// roll / pitch drift of LiDAR-only odometry between loops.
// Also reads and writes the g2o text format (VERTEX_SE3:QUAT / EDGE_SE3:QUAT; the vertical
// priors and the up direction in comment lines that g2o ignores).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

using NodeId = std::int64_t;
/// Information matrix of a relative pose, ordered (translation x y z, rotation x y z).
using Information6 = Eigen::Matrix<double, 6, 6>;

enum class EdgeKind { kOdometry, kIntraLoop, kInterLoop };

struct PoseGraphEdge {
  NodeId from = 0;
  NodeId to = 0;
  Pose3 T_from_to = Pose3::Identity();  ///< pose of `to` expressed in the frame of `from`
  Information6 information = Information6::Identity();
  EdgeKind kind = EdgeKind::kOdometry;
  bool enabled = true;  ///< false once rejected as an outlier; kept for the record

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct PoseGraphConfig {
  /// Scale of the Cauchy kernel on loop edges, in units of the whitened error (a chi value);
  /// errors well above it are down-weighted. Odometry edges use a plain squared loss. 3 is
  /// about the 95 % chi value of a 6-dof error, so consistent loops keep most of their weight.
  double loop_kernel_scale = 3.0;
  /// Graduated non-convexity: the first solve uses this wider scale (a drifted initial guess
  /// puts good loops far out in the kernel's tail too), and each following solve divides it by
  /// 4 until `loop_kernel_scale` is reached. Must be >= loop_kernel_scale.
  double loop_kernel_initial_scale = 256.0;
  /// After a solve, an enabled loop edge with chi2 (whitened squared error) above this gate is
  /// disabled and the graph is solved again. 6 dof: chi2(0.999) ~ 22.5. <= 0 disables the gate.
  double loop_outlier_chi2 = 22.5;
  /// At most this many solve / reject rounds after the kernel schedule.
  int max_outlier_rounds = 5;
  /// After the outliers are out, solve once more without the kernel: the kernel is for
  /// finding outliers; the inliers' plain least-squares optimum is the better estimate.
  bool final_least_squares = true;
  /// Scale of the Cauchy kernel on vertical priors (whitened units, 3 residuals): a submap
  /// whose "walls" are not vertical (a sloped roof, a leaning fence) loses its pull.
  double vertical_kernel_scale = 2.0;
  int max_iterations = 100;
  double function_tolerance = 1e-10;
  int num_threads = 1;

  Status Validate() const;
};

struct PoseGraphSummary {
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  int rounds = 0;
  std::vector<std::size_t> rejected_edges;  ///< indices into edges() switched off this call
  bool converged = false;
};

class PoseGraph {
 public:
  explicit PoseGraph(const PoseGraphConfig& config = PoseGraphConfig()) : config_(config) {}

  /// Adds or replaces a node's current estimate.
  void SetNodePose(NodeId id, const Pose3& pose);
  bool HasNode(NodeId id) const { return nodes_.count(id) > 0; }
  /// Fixed nodes are not moved by Optimize (the reference method fixes only the very first).
  void SetFixed(NodeId id, bool fixed);
  /// Fails when a node is missing, the pose is invalid or the information matrix is not
  /// symmetric positive definite. Returns the edge index.
  StatusOr<std::size_t> AddEdge(const PoseGraphEdge& edge);

  /// Prior on the up direction of a node: `information` [rad^-2] on the unit up vector in the
  /// node's frame (VerticalEvidence::information; symmetric positive semi-definite). A zero
  /// matrix removes the prior. Fails for a missing node or an invalid matrix.
  Status SetVerticalPrior(NodeId id, const Eigen::Matrix3d& information);
  const std::map<NodeId, Eigen::Matrix3d, std::less<NodeId>,
                 Eigen::aligned_allocator<std::pair<const NodeId, Eigen::Matrix3d>>>&
  vertical_priors() const {
    return vertical_priors_;
  }
  /// Up direction of the fixed nodes' frame (unit), estimated by Optimize when there are
  /// vertical priors; the frame's z axis before.
  const Eigen::Vector3d& up() const { return up_; }
  /// Starting value of the up direction (normalised; ignored unless finite and non-zero).
  void SetUp(const Eigen::Vector3d& up);

  /// Solves the graph; needs at least one fixed node in every connected component with edges.
  StatusOr<PoseGraphSummary> Optimize();

  const Pose3& NodePose(NodeId id) const { return nodes_.at(id); }
  const std::map<NodeId, Pose3, std::less<NodeId>,
                 Eigen::aligned_allocator<std::pair<const NodeId, Pose3>>>&
  nodes() const {
    return nodes_;
  }
  const std::vector<PoseGraphEdge, Eigen::aligned_allocator<PoseGraphEdge>>& edges() const {
    return edges_;
  }
  const std::set<NodeId>& fixed() const { return fixed_; }
  /// Whitened squared error of an edge under the current node estimates.
  double EdgeChi2(std::size_t edge_index) const;

  void set_config(const PoseGraphConfig& config) { config_ = config; }
  const PoseGraphConfig& config() const { return config_; }

  /// g2o text: VERTEX_SE3:QUAT for nodes, FIX for fixed ones, EDGE_SE3:QUAT for enabled edges
  /// (upper triangle of the information matrix). Edge kinds are kept in a comment
  /// `# MSM_EDGE_KIND <index> <kind> <enabled>` that g2o ignores.
  Status WriteG2o(std::ostream& out) const;
  /// Reads what WriteG2o writes (and plain g2o SE3 files); errors name the line.
  static StatusOr<PoseGraph> ReadG2o(std::istream& in, const std::string& source_name,
                                     const PoseGraphConfig& config = PoseGraphConfig());

 private:
  PoseGraphConfig config_;
  std::map<NodeId, Pose3, std::less<NodeId>,
           Eigen::aligned_allocator<std::pair<const NodeId, Pose3>>>
      nodes_;
  std::set<NodeId> fixed_;
  std::vector<PoseGraphEdge, Eigen::aligned_allocator<PoseGraphEdge>> edges_;
  std::map<NodeId, Eigen::Matrix3d, std::less<NodeId>,
           Eigen::aligned_allocator<std::pair<const NodeId, Eigen::Matrix3d>>>
      vertical_priors_;
  Eigen::Vector3d up_ = Eigen::Vector3d::UnitZ();
};

/// Name used in files and logs: "odometry", "intra_loop", "inter_loop".
const char* EdgeKindName(EdgeKind kind);
StatusOr<EdgeKind> EdgeKindFromName(const std::string& name);

}  // namespace core
}  // namespace multisession_mapper
