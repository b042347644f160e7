#include "multisession_mapper/core/pose_graph.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <istream>
#include <memory>
#include <ostream>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

// Residual of one relative-pose measurement: translation error in the frame of `from` and
// twice the vector part of the rotation error quaternion (the small-angle rotation vector),
// whitened by the square root of the information matrix.
class RelativePoseResidual {
 public:
  RelativePoseResidual(const Pose3& T_from_to, const Eigen::Matrix<double, 6, 6>& sqrt_info)
      : t_meas_(T_from_to.translation()),
        q_meas_(Eigen::Quaterniond(T_from_to.rotation()).normalized()),
        sqrt_info_(sqrt_info) {}

  template <typename T>
  bool operator()(const T* p_a_ptr, const T* q_a_ptr, const T* p_b_ptr, const T* q_b_ptr,
                  T* residual_ptr) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(p_a_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_b(p_b_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_b(q_b_ptr);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Matrix<T, 3, 1> t_ab = q_a_inv * (p_b - p_a);
    const Eigen::Quaternion<T> q_ab = q_a_inv * q_b;
    const Eigen::Quaternion<T> dq = q_meas_.template cast<T>().conjugate() * q_ab;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> residual(residual_ptr);
    residual.template head<3>() = t_ab - t_meas_.template cast<T>();
    residual.template tail<3>() = T(2.0) * dq.vec();
    residual.applyOnTheLeft(sqrt_info_.template cast<T>());
    return true;
  }

 private:
  Eigen::Vector3d t_meas_;
  Eigen::Quaterniond q_meas_;
  Eigen::Matrix<double, 6, 6> sqrt_info_;
};

// Residual of a vertical prior: the fixed frame's up direction g seen from the node,
// u = q^-1 g, whitened by the square root of the prior's information (u^T I u = |S u|^2).
// For the true vertical the walls' normals are perpendicular to u and the residual is ~0.
class VerticalPriorResidual {
 public:
  explicit VerticalPriorResidual(const Eigen::Matrix3d& sqrt_info) : sqrt_info_(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q_ptr, const T* up_ptr, T* residual_ptr) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> up(up_ptr);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> residual(residual_ptr);
    residual = sqrt_info_.template cast<T>() * (q.conjugate() * up);
    return true;
  }

 private:
  Eigen::Matrix3d sqrt_info_;
};

// S with S^T S = information, for a symmetric positive semi-definite 3x3 matrix.
Eigen::Matrix3d SqrtInformation3(const Eigen::Matrix3d& information) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(information);
  const Eigen::Vector3d roots = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return roots.asDiagonal() * solver.eigenvectors().transpose();
}

bool IsInformation3(const Eigen::Matrix3d& information) {
  if (!information.allFinite() || !information.isApprox(information.transpose(), 1e-9)) {
    return false;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(information);
  return solver.eigenvalues()(0) >= -1e-9 * std::max(1.0, solver.eigenvalues()(2));
}

Eigen::Matrix<double, 6, 6> SqrtInformation(const Information6& information) {
  // information = L L^T  =>  r^T information r = |L^T r|^2.
  return Eigen::LLT<Information6>(information).matrixL().transpose();
}

// Our rotation residual is 2 * vec(dq); g2o's SE3:QUAT edge error uses vec(dq).
const Eigen::Matrix<double, 6, 1> kG2oScale =
    (Eigen::Matrix<double, 6, 1>() << 1, 1, 1, 2, 2, 2).finished();

void WritePose(std::ostream& out, const Pose3& pose) {
  const Eigen::Quaterniond q(pose.rotation());
  const Eigen::Vector3d& t = pose.translation();
  out << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z()
      << ' ' << q.w();
}

bool ReadPose(std::istream& in, Pose3* pose) {
  double v[7];
  for (double& x : v) {
    if (!(in >> x) || !std::isfinite(x)) return false;
  }
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (q.norm() < 1e-9) return false;
  *pose = se3::FromTranslationQuaternion(Eigen::Vector3d(v[0], v[1], v[2]), q);
  return true;
}

}  // namespace

const char* EdgeKindName(EdgeKind kind) {
  switch (kind) {
    case EdgeKind::kOdometry:
      return "odometry";
    case EdgeKind::kIntraLoop:
      return "intra_loop";
    case EdgeKind::kInterLoop:
      return "inter_loop";
  }
  return "unknown";
}

StatusOr<EdgeKind> EdgeKindFromName(const std::string& name) {
  for (EdgeKind kind : {EdgeKind::kOdometry, EdgeKind::kIntraLoop, EdgeKind::kInterLoop}) {
    if (name == EdgeKindName(kind)) return kind;
  }
  return Status::Error("unknown edge kind '" + name + "'");
}

Status PoseGraphConfig::Validate() const {
  if (!(loop_kernel_scale > 0.0) || !std::isfinite(loop_kernel_scale)) {
    return Status::Error("pose_graph.loop_kernel_scale must be > 0");
  }
  if (!std::isfinite(loop_outlier_chi2)) {
    return Status::Error("pose_graph.loop_outlier_chi2 must be finite");
  }
  if (!std::isfinite(loop_kernel_initial_scale) || loop_kernel_initial_scale < loop_kernel_scale) {
    return Status::Error("pose_graph.loop_kernel_initial_scale must be >= loop_kernel_scale");
  }
  if (max_outlier_rounds < 1) return Status::Error("pose_graph.max_outlier_rounds must be >= 1");
  if (max_iterations < 1) return Status::Error("pose_graph.max_iterations must be >= 1");
  if (!(function_tolerance > 0.0)) return Status::Error("pose_graph.function_tolerance must be > 0");
  if (num_threads < 1) return Status::Error("pose_graph.num_threads must be >= 1");
  return Status::Ok();
}

void PoseGraph::SetNodePose(NodeId id, const Pose3& pose) { nodes_[id] = se3::Normalized(pose); }

void PoseGraph::SetFixed(NodeId id, bool fixed) {
  if (fixed) {
    fixed_.insert(id);
  } else {
    fixed_.erase(id);
  }
}

Status PoseGraph::SetVerticalPrior(NodeId id, const Eigen::Matrix3d& information) {
  if (!HasNode(id)) {
    return Status::Error("vertical prior for missing pose graph node " + std::to_string(id));
  }
  if (!IsInformation3(information)) {
    return Status::Error("vertical prior of node " + std::to_string(id) +
                         " is not symmetric positive semi-definite");
  }
  if (information.isZero(0.0)) {
    vertical_priors_.erase(id);
  } else {
    vertical_priors_[id] = 0.5 * (information + information.transpose());
  }
  return Status::Ok();
}

void PoseGraph::SetUp(const Eigen::Vector3d& up) {
  if (up.allFinite() && up.norm() > 1e-9) up_ = up.normalized();
}

StatusOr<std::size_t> PoseGraph::AddEdge(const PoseGraphEdge& edge) {
  if (!HasNode(edge.from) || !HasNode(edge.to)) {
    return Status::Error("pose graph edge " + std::to_string(edge.from) + " -> " +
                         std::to_string(edge.to) + " refers to a missing node");
  }
  if (edge.from == edge.to) return Status::Error("pose graph edge from a node to itself");
  if (!se3::IsValid(edge.T_from_to, 1e-4)) {
    return Status::Error("pose graph edge " + std::to_string(edge.from) + " -> " +
                         std::to_string(edge.to) + " has an invalid relative pose");
  }
  if (!edge.information.allFinite() ||
      !edge.information.isApprox(edge.information.transpose(), 1e-9) ||
      Eigen::LLT<Information6>(edge.information).info() != Eigen::Success) {
    return Status::Error("pose graph edge " + std::to_string(edge.from) + " -> " +
                         std::to_string(edge.to) +
                         " information matrix is not symmetric positive definite");
  }
  PoseGraphEdge copy = edge;
  copy.T_from_to = se3::Normalized(edge.T_from_to);
  edges_.push_back(copy);
  return edges_.size() - 1;
}

double PoseGraph::EdgeChi2(std::size_t edge_index) const {
  const PoseGraphEdge& edge = edges_.at(edge_index);
  const Pose3& a = nodes_.at(edge.from);
  const Pose3& b = nodes_.at(edge.to);
  const Eigen::Vector3d p_a = a.translation(), p_b = b.translation();
  const Eigen::Quaterniond q_a(a.rotation()), q_b(b.rotation());
  const RelativePoseResidual residual(edge.T_from_to, SqrtInformation(edge.information));
  Eigen::Matrix<double, 6, 1> r;
  residual(p_a.data(), q_a.coeffs().data(), p_b.data(), q_b.coeffs().data(), r.data());
  return r.squaredNorm();
}

StatusOr<PoseGraphSummary> PoseGraph::Optimize() {
  Status valid = config_.Validate();
  if (!valid.ok()) return valid;
  PoseGraphSummary summary;
  if (edges_.empty() && vertical_priors_.empty()) {
    summary.converged = true;
    return summary;
  }
  bool any_fixed = false;
  for (NodeId id : fixed_) any_fixed = any_fixed || HasNode(id);
  if (!any_fixed) return Status::Error("pose graph has edges but no fixed node (gauge freedom)");

  // Kernel schedule: wide to narrow, then the outlier rounds at the final scale.
  std::vector<double> scales;
  for (double s = config_.loop_kernel_initial_scale; s > config_.loop_kernel_scale; s /= 4.0) {
    scales.push_back(s);
  }
  const std::size_t annealing_rounds = scales.size();
  for (int i = 0; i < config_.max_outlier_rounds; ++i) scales.push_back(config_.loop_kernel_scale);
  const double kNoKernel = 0.0;

  for (std::size_t round = 0; round < scales.size(); ++round) {
    // Parameter storage: translation (3) and quaternion (x y z w, Eigen's order) per node.
    std::map<NodeId, std::array<double, 7>> params;
    for (const auto& [id, pose] : nodes_) {
      std::array<double, 7> p;
      const Eigen::Quaterniond q(pose.rotation());
      p = {pose.translation().x(), pose.translation().y(), pose.translation().z(),
           q.x(), q.y(), q.z(), q.w()};
      params[id] = p;
    }
    ceres::Problem problem;
    for (const PoseGraphEdge& edge : edges_) {
      if (!edge.enabled) continue;
      auto* cost = new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 3, 4, 3, 4>(
          new RelativePoseResidual(edge.T_from_to, SqrtInformation(edge.information)));
      ceres::LossFunction* loss = (edge.kind == EdgeKind::kOdometry || scales[round] == kNoKernel)
                                      ? nullptr
                                      : new ceres::CauchyLoss(scales[round]);
      double* a = params[edge.from].data();
      double* b = params[edge.to].data();
      problem.AddResidualBlock(cost, loss, a, a + 3, b, b + 3);
    }
    // One up direction for the whole graph; each prior ties its node's tilt to it.
    std::array<double, 3> up = {up_.x(), up_.y(), up_.z()};
    for (const auto& [id, information] : vertical_priors_) {
      const auto node = params.find(id);
      if (node == params.end()) continue;
      auto* cost = new ceres::AutoDiffCostFunction<VerticalPriorResidual, 3, 4, 3>(
          new VerticalPriorResidual(SqrtInformation3(information)));
      problem.AddResidualBlock(cost, new ceres::CauchyLoss(config_.vertical_kernel_scale),
                               node->second.data() + 3, up.data());
    }
    if (problem.HasParameterBlock(up.data())) {
      problem.SetManifold(up.data(), new ceres::SphereManifold<3>());
    }
    for (auto& [id, p] : params) {
      const bool fixed = fixed_.count(id) > 0;
      if (problem.HasParameterBlock(p.data()) && fixed) problem.SetParameterBlockConstant(p.data());
      if (!problem.HasParameterBlock(p.data() + 3)) continue;  // a node without edges / prior
      problem.SetManifold(p.data() + 3, new ceres::EigenQuaternionManifold());
      if (fixed) problem.SetParameterBlockConstant(p.data() + 3);
    }
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    options.max_num_iterations = config_.max_iterations;
    options.function_tolerance = config_.function_tolerance;
    options.num_threads = config_.num_threads;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary ceres_summary;
    ceres::Solve(options, &problem, &ceres_summary);
    if (!ceres_summary.IsSolutionUsable()) {
      return Status::Error("pose graph solve failed: " + ceres_summary.message);
    }
    for (auto& [id, p] : params) {
      nodes_[id] = se3::FromTranslationQuaternion(Eigen::Vector3d(p[0], p[1], p[2]),
                                                  Eigen::Quaterniond(p[6], p[3], p[4], p[5]));
    }
    up_ = Eigen::Vector3d(up[0], up[1], up[2]).normalized();
    if (round == 0) summary.initial_cost = ceres_summary.initial_cost;
    summary.final_cost = ceres_summary.final_cost;
    summary.iterations += static_cast<int>(ceres_summary.iterations.size());
    summary.rounds = static_cast<int>(round) + 1;
    summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;

    if (round < annealing_rounds || scales[round] == kNoKernel) continue;
    bool done = config_.loop_outlier_chi2 <= 0.0;
    // Switch off the single worst loop above the gate, then solve again: removing one at a
    // time keeps good loops that were only strained by a bad one.
    double worst_chi2 = config_.loop_outlier_chi2;
    std::size_t worst = edges_.size();
    for (std::size_t i = 0; i < edges_.size(); ++i) {
      if (!edges_[i].enabled || edges_[i].kind == EdgeKind::kOdometry) continue;
      const double chi2 = EdgeChi2(i);
      if (chi2 > worst_chi2) {
        worst_chi2 = chi2;
        worst = i;
      }
    }
    if (!done && worst != edges_.size()) {
      edges_[worst].enabled = false;
      summary.rejected_edges.push_back(worst);
    } else {
      done = true;
    }
    if (done || round + 1 == scales.size()) {
      // Drop the remaining kernel rounds; optionally finish with plain least squares.
      scales.resize(round + 1);
      if (config_.final_least_squares) scales.push_back(kNoKernel);
    }
  }
  return summary;
}

Status PoseGraph::WriteG2o(std::ostream& out) const {
  out.precision(12);
  out << "# multisession_mapper pose graph (g2o SE3:QUAT)\n";
  for (const auto& [id, pose] : nodes_) {
    out << "VERTEX_SE3:QUAT " << id << ' ';
    WritePose(out, pose);
    out << '\n';
  }
  for (NodeId id : fixed_) {
    if (HasNode(id)) out << "FIX " << id << '\n';
  }
  // Vertical priors and the up direction: comment lines, ignored by g2o.
  if (!vertical_priors_.empty()) {
    out << "# MSM_UP " << up_.x() << ' ' << up_.y() << ' ' << up_.z() << '\n';
  }
  for (const auto& [id, information] : vertical_priors_) {
    out << "# MSM_VERTICAL_PRIOR " << id;
    for (int r = 0; r < 3; ++r) {
      for (int c = r; c < 3; ++c) out << ' ' << information(r, c);
    }
    out << '\n';
  }
  for (const PoseGraphEdge& edge : edges_) {
    out << "# MSM_EDGE_KIND " << EdgeKindName(edge.kind) << '\n';
    if (!edge.enabled) out << "#DISABLED ";
    out << "EDGE_SE3:QUAT " << edge.from << ' ' << edge.to << ' ';
    WritePose(out, edge.T_from_to);
    const Information6 g2o_info =
        kG2oScale.asDiagonal() * edge.information * kG2oScale.asDiagonal();
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) out << ' ' << g2o_info(r, c);
    }
    out << '\n';
  }
  if (!out) return Status::Error("error while writing the g2o graph");
  return Status::Ok();
}

StatusOr<PoseGraph> PoseGraph::ReadG2o(std::istream& in, const std::string& source_name,
                                       const PoseGraphConfig& config) {
  PoseGraph graph(config);
  std::string line;
  int line_number = 0;
  EdgeKind pending_kind = EdgeKind::kOdometry;
  auto error = [&](const std::string& what) {
    return Status::Error(source_name + ":" + std::to_string(line_number) + ": " + what);
  };
  while (std::getline(in, line)) {
    ++line_number;
    bool enabled = true;
    if (line.rfind("# MSM_EDGE_KIND ", 0) == 0) {
      StatusOr<EdgeKind> kind = EdgeKindFromName(line.substr(16));
      if (!kind.ok()) return error(kind.status().message());
      pending_kind = kind.value();
      continue;
    }
    if (line.rfind("# MSM_UP ", 0) == 0) {
      std::istringstream fields(line.substr(9));
      Eigen::Vector3d up;
      if (!(fields >> up.x() >> up.y() >> up.z()) || !up.allFinite() || up.norm() < 1e-6) {
        return error("malformed MSM_UP");
      }
      graph.SetUp(up);
      continue;
    }
    if (line.rfind("# MSM_VERTICAL_PRIOR ", 0) == 0) {
      std::istringstream fields(line.substr(21));
      NodeId id;
      Eigen::Matrix3d information;
      if (!(fields >> id)) return error("malformed MSM_VERTICAL_PRIOR");
      for (int r = 0; r < 3; ++r) {
        for (int c = r; c < 3; ++c) {
          if (!(fields >> information(r, c))) {
            return error("MSM_VERTICAL_PRIOR needs a node id and 6 information values");
          }
          information(c, r) = information(r, c);
        }
      }
      const Status set = graph.SetVerticalPrior(id, information);
      if (!set.ok()) return error(set.message());
      continue;
    }
    if (line.rfind("#DISABLED ", 0) == 0) {
      enabled = false;
      line = line.substr(10);
    }
    std::istringstream fields(line);
    std::string tag;
    if (!(fields >> tag) || tag[0] == '#') continue;
    if (tag == "VERTEX_SE3:QUAT") {
      NodeId id;
      Pose3 pose;
      if (!(fields >> id) || !ReadPose(fields, &pose)) return error("malformed VERTEX_SE3:QUAT");
      if (graph.HasNode(id)) return error("duplicate vertex " + std::to_string(id));
      graph.SetNodePose(id, pose);
    } else if (tag == "FIX") {
      NodeId id;
      if (!(fields >> id)) return error("malformed FIX");
      if (!graph.HasNode(id)) return error("FIX of unknown vertex " + std::to_string(id));
      graph.SetFixed(id, true);
    } else if (tag == "EDGE_SE3:QUAT") {
      PoseGraphEdge edge;
      if (!(fields >> edge.from >> edge.to) || !ReadPose(fields, &edge.T_from_to)) {
        return error("malformed EDGE_SE3:QUAT");
      }
      Information6 g2o_info;
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c) {
          if (!(fields >> g2o_info(r, c))) return error("EDGE_SE3:QUAT needs 21 information values");
          g2o_info(c, r) = g2o_info(r, c);
        }
      }
      const Eigen::Matrix<double, 6, 1> inv_scale = kG2oScale.cwiseInverse();
      edge.information = inv_scale.asDiagonal() * g2o_info * inv_scale.asDiagonal();
      edge.kind = pending_kind;
      edge.enabled = enabled;
      StatusOr<std::size_t> added = graph.AddEdge(edge);
      if (!added.ok()) return error(added.status().message());
      pending_kind = EdgeKind::kOdometry;
    } else {
      return error("unknown g2o tag '" + tag + "'");
    }
  }
  return graph;
}

}  // namespace core
}  // namespace multisession_mapper
