#include "multisession_mapper/core/descriptor_database.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <utility>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <nanoflann.hpp>

#include "multisession_mapper/core/checksum.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr char kMagic[8] = {'M', 'S', 'M', 'P', 'R', 'D', 'B', '1'};
constexpr std::uint32_t kFormatVersion = 1;
// Sanity limits that a real database never reaches; they keep a corrupt header from asking for
// absurd allocations before the size check against the file length.
constexpr std::uint32_t kMaxKeyDim = 1u << 16;
constexpr std::uint64_t kMaxMatrixSize = 1u << 20;
constexpr std::uint32_t kMaxSessionNameLength = 4096;


class HashingWriter {
 public:
  explicit HashingWriter(std::ostream* out) : out_(out) {}
  void Bytes(const void* data, std::size_t size) {
    hash_ = Fnv1a64(data, size, hash_);
    out_->write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  template <typename T>
  void Value(const T& value) {
    Bytes(&value, sizeof(T));
  }
  std::uint64_t hash() const { return hash_; }

 private:
  std::ostream* out_;
  std::uint64_t hash_ = kFnv1a64Offset;
};

class HashingReader {
 public:
  HashingReader(std::istream* in, std::uint64_t size) : in_(in), remaining_(size) {}
  // False (and reads nothing) when fewer than `size` bytes are left or the stream fails.
  bool Bytes(void* data, std::size_t size) {
    if (size > remaining_) return false;
    in_->read(static_cast<char*>(data), static_cast<std::streamsize>(size));
    if (!*in_) return false;
    remaining_ -= size;
    hash_ = Fnv1a64(data, size, hash_);
    return true;
  }
  template <typename T>
  bool Value(T* value) {
    return Bytes(value, sizeof(T));
  }
  std::uint64_t remaining() const { return remaining_; }
  std::uint64_t hash() const { return hash_; }

 private:
  std::istream* in_;
  std::uint64_t remaining_;
  std::uint64_t hash_ = kFnv1a64Offset;
};

// nanoflann result set: every index within `radius` (squared distance, inclusive), stopping
// the search once `cap` entries were collected.
class CappedRadiusResultSet {
 public:
  CappedRadiusResultSet(float radius_sq, std::size_t cap, std::vector<std::size_t>* out)
      : radius_sq_(radius_sq), cap_(cap), out_(out) {}
  std::size_t size() const { return out_->size(); }
  bool full() const { return true; }
  float worstDist() const { return radius_sq_; }
  bool addPoint(float dist, std::size_t index) {
    if (dist <= radius_sq_) out_->push_back(index);
    if (out_->size() >= cap_) {
      capped_ = true;
      return false;
    }
    return true;
  }
  bool capped() const { return capped_; }

 private:
  float radius_sq_;
  std::size_t cap_;
  std::vector<std::size_t>* out_;
  bool capped_ = false;
};

// Principal components are estimated from at most this many (evenly spaced) entries.
constexpr std::size_t kMaxPcaSamples = 10000;

bool AllFinite(const std::vector<float>& values) {
  return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
}

}  // namespace

Status DescriptorDatabaseConfig::Validate() const {
  const std::string p = "descriptor_database.";
  if (!std::isfinite(d_alpha_ring_histogram) || d_alpha_ring_histogram < 0.0) {
    return Status::Error(p + "d_alpha_ring_histogram must be finite and >= 0");
  }
  if (!std::isfinite(d_alpha_scan_context) || d_alpha_scan_context < 0.0) {
    return Status::Error(p + "d_alpha_scan_context must be finite and >= 0");
  }
  if (num_neighbors < 1 || num_neighbors > 1000) {
    return Status::Error(p + "num_neighbors must be in [1, 1000], got " +
                         std::to_string(num_neighbors));
  }
  for (int candidates : {rerank_candidates_ring_histogram, rerank_candidates_scan_context}) {
    if (candidates < 1 || candidates > 10000) {
      return Status::Error(p + "rerank_candidates_* must be in [1, 10000], got " +
                           std::to_string(candidates));
    }
  }
  if (index_dim < 1 || index_dim > 1024) {
    return Status::Error(p + "index_dim must be in [1, 1024], got " + std::to_string(index_dim));
  }
  if (max_exact_candidates < 1) {
    return Status::Error(p + "max_exact_candidates must be >= 1");
  }
  if (!std::isfinite(search_eps) || search_eps < 0.0 || search_eps > 100.0) {
    return Status::Error(p + "search_eps must be in [0, 100], got " + std::to_string(search_eps));
  }
  if (leaf_max_size < 1 || leaf_max_size > 1000) {
    return Status::Error(p + "leaf_max_size must be in [1, 1000]");
  }
  return scan_context.Validate();
}

struct DescriptorDatabase::Impl {
  // nanoflann's dataset interface over `keys`.
  struct Adaptor {
    const Impl* impl;
    std::size_t kdtree_get_point_count() const { return impl->entries.size(); }
    float kdtree_get_pt(std::size_t index, std::size_t dim) const {
      return impl->index_points[index * static_cast<std::size_t>(impl->index_dim) + dim];
    }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox& /*bb*/) const {
      return false;
    }
  };
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<
      nanoflann::L2_Adaptor<float, Adaptor, float, std::size_t>, Adaptor, -1, std::size_t>;

  DescriptorDatabaseConfig config;
  DescriptorKind kind = DescriptorKind::kRingHistogram;
  int key_dim = 0;
  int rows = 0;
  int cols = 0;
  std::vector<DatabaseEntry> entries;
  std::vector<float> keys;      // entries.size() x key_dim
  std::vector<float> matrices;  // entries.size() x rows*cols
  std::optional<ScanContextDescriptor> scan_context;
  // What the kd-tree indexes: the keys themselves, or their principal-component projection
  // basis * (key - mean) when `projected` (ring histogram with key_dim > config.index_dim).
  bool projected = false;
  int index_dim = 0;
  Eigen::MatrixXf basis;  // index_dim x key_dim, orthonormal rows
  Eigen::VectorXf mean;   // key_dim
  std::vector<float> index_points;  // entries.size() x index_dim
  Adaptor adaptor{this};
  std::unique_ptr<Tree> tree;

  std::size_t matrix_size() const { return static_cast<std::size_t>(rows) * cols; }

  void ComputeProjection() {
    const std::size_t n = entries.size();
    const std::size_t stride = std::max<std::size_t>(1, (n + kMaxPcaSamples - 1) / kMaxPcaSamples);
    const Eigen::Map<const Eigen::MatrixXf> all(keys.data(), key_dim, static_cast<Eigen::Index>(n));
    const Eigen::Index samples = static_cast<Eigen::Index>((n + stride - 1) / stride);
    Eigen::MatrixXd x(key_dim, samples);
    for (Eigen::Index j = 0; j < samples; ++j) {
      x.col(j) = all.col(j * static_cast<Eigen::Index>(stride)).cast<double>();
    }
    const Eigen::VectorXd m = x.rowwise().mean();
    x.colwise() -= m;
    const Eigen::MatrixXd covariance = x * x.transpose() / static_cast<double>(samples);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(covariance);
    // Eigenvalues ascend: the last index_dim eigenvectors span the most variance.
    basis = solver.eigenvectors().rightCols(index_dim).transpose().cast<float>();
    mean = m.cast<float>();
  }

  void Project(const float* key, float* out) const {
    const Eigen::Map<const Eigen::VectorXf> k(key, key_dim);
    Eigen::Map<Eigen::VectorXf>(out, index_dim) = basis * (k - mean);
  }

  void BuildTree() {
    tree.reset();
    index_points.clear();
    if (entries.empty()) return;
    projected = kind == DescriptorKind::kRingHistogram && key_dim > config.index_dim;
    index_dim = projected ? config.index_dim : key_dim;
    if (projected) {
      ComputeProjection();
      index_points.resize(entries.size() * static_cast<std::size_t>(index_dim));
      const Eigen::Map<const Eigen::MatrixXf> all(keys.data(), key_dim,
                                                  static_cast<Eigen::Index>(entries.size()));
      Eigen::Map<Eigen::MatrixXf>(index_points.data(), index_dim,
                                  static_cast<Eigen::Index>(entries.size())) =
          basis * (all.colwise() - mean);
    } else {
      index_points = keys;
    }
    tree = std::make_unique<Tree>(
        index_dim, adaptor,
        nanoflann::KDTreeSingleIndexAdaptorParams(static_cast<std::size_t>(config.leaf_max_size)));
    tree->buildIndex();
  }

  float KeyDistance(const float* query, std::size_t index) const {
    const float* stored = keys.data() + index * static_cast<std::size_t>(key_dim);
    float sum = 0.0f;
    for (int i = 0; i < key_dim; ++i) {
      const float d = query[i] - stored[i];
      sum += d * d;
    }
    return std::sqrt(sum);
  }

  Status CheckDescriptor(const PlaceDescriptor& d) const {
    if (d.kind != kind) {
      return Status::Error(std::string("descriptor kind ") + DescriptorKindName(d.kind) +
                           " does not match the database's " + DescriptorKindName(kind));
    }
    if (d.key.size() != static_cast<std::size_t>(key_dim) || d.matrix.size() != matrix_size() ||
        d.rows != rows || d.cols != cols) {
      return Status::Error("descriptor size (key " + std::to_string(d.key.size()) + ", matrix " +
                           std::to_string(d.rows) + "x" + std::to_string(d.cols) +
                           ") does not match the database's (key " + std::to_string(key_dim) +
                           ", matrix " + std::to_string(rows) + "x" + std::to_string(cols) + ")");
    }
    return Status::Ok();
  }
};

DescriptorDatabase::DescriptorDatabase(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
DescriptorDatabase::DescriptorDatabase(DescriptorDatabase&&) noexcept = default;
DescriptorDatabase& DescriptorDatabase::operator=(DescriptorDatabase&&) noexcept = default;
DescriptorDatabase::~DescriptorDatabase() = default;

StatusOr<DescriptorDatabase> DescriptorDatabase::Create(const DescriptorDatabaseConfig& config,
                                                        DescriptorKind kind, int key_dim,
                                                        int matrix_rows, int matrix_cols) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  if (kind != DescriptorKind::kRingHistogram && kind != DescriptorKind::kScanContext) {
    return Status::Error("descriptor_database: unknown descriptor kind " +
                         std::to_string(static_cast<std::uint32_t>(kind)));
  }
  if (key_dim < 1 || static_cast<std::uint32_t>(key_dim) > kMaxKeyDim) {
    return Status::Error("descriptor_database: key_dim must be in [1, 65536], got " +
                         std::to_string(key_dim));
  }
  auto impl = std::make_unique<Impl>();
  impl->config = config;
  impl->kind = kind;
  impl->key_dim = key_dim;
  if (kind == DescriptorKind::kRingHistogram) {
    if (matrix_rows != 0 || matrix_cols != 0) {
      return Status::Error("descriptor_database: ring_histogram descriptors have no matrix");
    }
  } else {
    if (matrix_rows != key_dim || matrix_cols < 4 ||
        static_cast<std::uint64_t>(matrix_rows) * matrix_cols > kMaxMatrixSize) {
      return Status::Error("descriptor_database: a scan_context matrix must have key_dim rows "
                           "and >= 4 columns, got " + std::to_string(matrix_rows) + "x" +
                           std::to_string(matrix_cols) + " with key_dim " +
                           std::to_string(key_dim));
    }
    ScanContextConfig sc = config.scan_context;
    sc.num_rings = matrix_rows;  // the stored size wins over the configured one
    sc.num_sectors = matrix_cols;
    auto matcher = ScanContextDescriptor::Create(sc);
    if (!matcher.ok()) return matcher.status();
    impl->scan_context.emplace(matcher.value());
  }
  impl->rows = matrix_rows;
  impl->cols = matrix_cols;
  return DescriptorDatabase(std::move(impl));
}

Status DescriptorDatabase::Insert(const std::vector<DatabaseEntry>& entries,
                                  const std::vector<PlaceDescriptor>& descriptors) {
  Impl& d = *impl_;
  if (entries.size() != descriptors.size()) {
    return Status::Error("descriptor_database: Insert got " + std::to_string(entries.size()) +
                         " entries but " + std::to_string(descriptors.size()) + " descriptors");
  }
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    Status status = d.CheckDescriptor(descriptors[i]);
    if (!status.ok()) {
      return Status::Error("descriptor_database: Insert item " + std::to_string(i) + ": " +
                           status.message());
    }
    if (!AllFinite(descriptors[i].key) || !AllFinite(descriptors[i].matrix) ||
        !std::isfinite(entries[i].stamp_s)) {
      return Status::Error("descriptor_database: Insert item " + std::to_string(i) +
                           " has a non-finite value");
    }
    if (entries[i].session.size() > kMaxSessionNameLength) {
      return Status::Error("descriptor_database: Insert item " + std::to_string(i) +
                           " has a session name longer than 4096 bytes");
    }
  }
  d.entries.reserve(d.entries.size() + entries.size());
  d.keys.reserve(d.keys.size() + entries.size() * static_cast<std::size_t>(d.key_dim));
  d.matrices.reserve(d.matrices.size() + entries.size() * d.matrix_size());
  for (std::size_t i = 0; i < entries.size(); ++i) {
    d.entries.push_back(entries[i]);
    d.keys.insert(d.keys.end(), descriptors[i].key.begin(), descriptors[i].key.end());
    d.matrices.insert(d.matrices.end(), descriptors[i].matrix.begin(),
                      descriptors[i].matrix.end());
  }
  d.BuildTree();
  return Status::Ok();
}

StatusOr<DatabaseQueryResult> DescriptorDatabase::Query(const PlaceDescriptor& descriptor,
                                                        int k) const {
  const Impl& d = *impl_;
  Status status = d.CheckDescriptor(descriptor);
  if (!status.ok()) return Status::Error("descriptor_database: Query: " + status.message());
  if (!AllFinite(descriptor.key)) {
    return Status::Error("descriptor_database: Query: descriptor has a non-finite value");
  }
  DatabaseQueryResult result;
  if (d.entries.empty() || !d.tree) return result;
  const std::size_t wanted =
      std::min<std::size_t>(k > 0 ? static_cast<std::size_t>(k) : d.config.num_neighbors,
                            d.entries.size());
  const bool scan_context = d.kind == DescriptorKind::kScanContext;
  const bool rerank = scan_context || d.projected;
  const int candidates = scan_context ? d.config.rerank_candidates_scan_context
                                      : d.config.rerank_candidates_ring_histogram;
  const std::size_t searched =
      rerank ? std::min<std::size_t>(
                   std::max<std::size_t>(wanted, static_cast<std::size_t>(candidates)),
                   d.entries.size())
             : wanted;
  using SearchMode = DescriptorDatabaseConfig::SearchMode;
  // Exhaustive (all entries compared) or a plain kd-tree on the full vectors: exact.
  result.exact = !scan_context && (!d.projected || searched == d.entries.size());
  std::vector<float> point(static_cast<std::size_t>(d.index_dim));
  if (d.projected) {
    d.Project(descriptor.key.data(), point.data());
  } else {
    point.assign(descriptor.key.begin(), descriptor.key.end());
  }
  std::vector<std::size_t> indices(searched);
  std::vector<float> squared(searched);
  nanoflann::KNNResultSet<float, std::size_t, std::size_t> knn(searched);
  knn.init(indices.data(), squared.data());
  // eps only on the ring histogram's projected tree (`projected` implies the ring histogram)
  // and only when approximate: the exact modes' proof below needs the true projected k
  // nearest, a tree over the full vectors reports itself exact, and Scan Context keeps the
  // candidates of the original's exact ring-key search (its time is in the re-ranking).
  const float eps = d.projected && d.config.search_mode == SearchMode::kApproximate
                        ? static_cast<float>(d.config.search_eps)
                        : 0.0f;
  d.tree->findNeighbors(knn, point.data(), nanoflann::SearchParams(32, eps));
  const std::size_t found = knn.size();
  indices.resize(found);
  squared.resize(found);
  const auto by_distance = [](const DatabaseNeighbor& a, const DatabaseNeighbor& b) {
    return a.distance < b.distance || (a.distance == b.distance && a.index < b.index);
  };

  result.neighbors.reserve(found);
  for (std::size_t i = 0; i < found; ++i) {
    DatabaseNeighbor n;
    n.index = indices[i];
    if (scan_context) {
      const ScanContextMatch match = d.scan_context->DistanceRaw(
          descriptor.matrix.data(), d.matrices.data() + indices[i] * d.matrix_size());
      n.distance = match.distance;
      n.yaw_rad = match.yaw_rad;
    } else if (d.projected) {
      n.distance = d.KeyDistance(descriptor.key.data(), indices[i]);
    } else {
      n.distance = std::sqrt(std::max(0.0f, squared[i]));
    }
    result.neighbors.push_back(n);
  }
  std::sort(result.neighbors.begin(), result.neighbors.end(), by_distance);

  // Exactness for the projected index: entries not seen yet have a projected distance of at
  // least the largest one seen, and a true distance of at least their projected one.
  if (d.projected && d.config.search_mode != SearchMode::kApproximate && found == searched &&
      searched < d.entries.size() && result.neighbors.size() >= wanted) {
    double radius = result.neighbors[wanted - 1].distance;
    if (d.config.search_mode == SearchMode::kExactWithinDAlpha) {
      radius = std::min(radius, d.config.DAlpha(d.kind));
    }
    const double largest_projected = std::sqrt(std::max(0.0f, squared.back()));
    result.exact = true;
    if (largest_projected < radius) {
      // Slack for float rounding of the projection.
      const double padded = radius * (1.0 + 1e-4) + 1e-6;
      std::vector<std::size_t> inside;
      CappedRadiusResultSet ball(static_cast<float>(padded * padded),
                                 static_cast<std::size_t>(d.config.max_exact_candidates), &inside);
      d.tree->findNeighbors(ball, point.data(), nanoflann::SearchParams());
      result.exact = !ball.capped();
      std::sort(indices.begin(), indices.end());
      for (std::size_t index : inside) {
        if (std::binary_search(indices.begin(), indices.end(), index)) continue;
        result.neighbors.push_back({index, d.KeyDistance(descriptor.key.data(), index), 0.0});
      }
      std::sort(result.neighbors.begin(), result.neighbors.end(), by_distance);
    }
  }
  if (result.neighbors.size() > wanted) result.neighbors.resize(wanted);
  result.matched = !result.neighbors.empty() &&
                   result.neighbors.front().distance <= d.config.DAlpha(d.kind);
  return result;
}

Status DescriptorDatabase::Write(std::ostream& out) const {
  const Impl& d = *impl_;
  // Session names are stored once; entries refer to them by index.
  std::vector<std::string> sessions;
  std::vector<std::uint32_t> session_of(d.entries.size());
  for (std::size_t i = 0; i < d.entries.size(); ++i) {
    auto it = std::find(sessions.begin(), sessions.end(), d.entries[i].session);
    if (it == sessions.end()) it = sessions.insert(sessions.end(), d.entries[i].session);
    session_of[i] = static_cast<std::uint32_t>(it - sessions.begin());
  }
  HashingWriter w(&out);
  w.Bytes(kMagic, sizeof(kMagic));
  w.Value<std::uint32_t>(kFormatVersion);
  w.Value<std::uint32_t>(static_cast<std::uint32_t>(d.kind));
  w.Value<std::uint32_t>(static_cast<std::uint32_t>(d.key_dim));
  w.Value<std::uint32_t>(static_cast<std::uint32_t>(d.rows));
  w.Value<std::uint32_t>(static_cast<std::uint32_t>(d.cols));
  w.Value<std::uint32_t>(static_cast<std::uint32_t>(sessions.size()));
  w.Value<std::uint64_t>(d.entries.size());
  for (const std::string& s : sessions) {
    w.Value<std::uint32_t>(static_cast<std::uint32_t>(s.size()));
    w.Bytes(s.data(), s.size());
  }
  for (std::size_t i = 0; i < d.entries.size(); ++i) {
    w.Value<std::uint32_t>(session_of[i]);
    w.Value<std::int32_t>(d.entries[i].submap_id);
    w.Value<double>(d.entries[i].stamp_s);
    w.Bytes(d.keys.data() + i * d.key_dim, sizeof(float) * d.key_dim);
    w.Bytes(d.matrices.data() + i * d.matrix_size(), sizeof(float) * d.matrix_size());
  }
  const std::uint64_t checksum = w.hash();
  out.write(reinterpret_cast<const char*>(&checksum), sizeof(checksum));
  if (!out) return Status::Error("descriptor_database: write failed");
  return Status::Ok();
}

Status DescriptorDatabase::Save(const std::string& path) const {
  std::error_code ec;
  const std::filesystem::path target(path);
  if (target.has_parent_path()) std::filesystem::create_directories(target.parent_path(), ec);
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return Status::Error("descriptor_database: cannot write " + tmp);
    Status written = Write(out);
    out.close();
    if (!written.ok() || !out) {
      std::filesystem::remove(tmp, ec);
      return Status::Error("descriptor_database: writing " + tmp + " failed");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    return Status::Error("descriptor_database: cannot move " + tmp + " to " + path);
  }
  return Status::Ok();
}

StatusOr<DescriptorDatabase> DescriptorDatabase::Load(const std::string& path,
                                                      const DescriptorDatabaseConfig& config) {
  const std::string where = "descriptor_database: " + path + ": ";
  std::error_code ec;
  const std::uintmax_t file_size = std::filesystem::file_size(path, ec);
  if (ec) return Status::Error(where + "cannot read the file (" + ec.message() + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error(where + "cannot open the file");
  return Read(in, file_size, path, config);
}

StatusOr<DescriptorDatabase> DescriptorDatabase::Read(std::istream& in, std::uint64_t file_size,
                                                      const std::string& source,
                                                      const DescriptorDatabaseConfig& config) {
  const std::string where = "descriptor_database: " + source + ": ";
  constexpr std::uint64_t kChecksumSize = sizeof(std::uint64_t);
  if (file_size < sizeof(kMagic) + kChecksumSize) {
    return Status::Error(where + "truncated (" + std::to_string(file_size) +
                         " bytes, smaller than a header)");
  }
  HashingReader r(&in, file_size - kChecksumSize);
  char magic[sizeof(kMagic)];
  if (!r.Bytes(magic, sizeof(magic)) || std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) {
    return Status::Error(where + "not a descriptor database (bad magic number)");
  }
  std::uint32_t version = 0, kind = 0, key_dim = 0, rows = 0, cols = 0, session_count = 0;
  std::uint64_t entry_count = 0;
  if (!r.Value(&version) || !r.Value(&kind) || !r.Value(&key_dim) || !r.Value(&rows) ||
      !r.Value(&cols) || !r.Value(&session_count) || !r.Value(&entry_count)) {
    return Status::Error(where + "truncated in the header");
  }
  if (version != kFormatVersion) {
    return Status::Error(where + "unsupported format version " + std::to_string(version) +
                         " (this build reads version " + std::to_string(kFormatVersion) + ")");
  }
  if (key_dim < 1 || key_dim > kMaxKeyDim ||
      static_cast<std::uint64_t>(rows) * cols > kMaxMatrixSize) {
    return Status::Error(where + "corrupt header (key_dim " + std::to_string(key_dim) +
                         ", matrix " + std::to_string(rows) + "x" + std::to_string(cols) + ")");
  }
  auto created = Create(config, static_cast<DescriptorKind>(kind), static_cast<int>(key_dim),
                        static_cast<int>(rows), static_cast<int>(cols));
  if (!created.ok()) return Status::Error(where + "corrupt header: " + created.status().message());
  DescriptorDatabase db = std::move(created).value();
  Impl& d = *db.impl_;

  // Every count is checked against the bytes left before anything is allocated.
  const std::uint64_t entry_bytes = 4 + 4 + 8 + 4ull * key_dim + 4ull * rows * cols;
  if (session_count > r.remaining() / 4 || entry_count > r.remaining() / entry_bytes) {
    return Status::Error(where + "truncated or corrupt: header announces " +
                         std::to_string(entry_count) + " entries and " +
                         std::to_string(session_count) + " sessions, more than the file holds");
  }
  std::vector<std::string> sessions(session_count);
  for (std::string& s : sessions) {
    std::uint32_t length = 0;
    if (!r.Value(&length) || length > kMaxSessionNameLength || length > r.remaining()) {
      return Status::Error(where + "truncated or corrupt session name table");
    }
    s.resize(length);
    if (!r.Bytes(s.data(), length)) return Status::Error(where + "truncated session name");
  }
  if (entry_count > r.remaining() / entry_bytes) {
    return Status::Error(where + "truncated: " + std::to_string(entry_count) +
                         " entries announced, the file is too short");
  }
  d.entries.resize(entry_count);
  d.keys.resize(entry_count * key_dim);
  d.matrices.resize(entry_count * d.matrix_size());
  for (std::uint64_t i = 0; i < entry_count; ++i) {
    std::uint32_t session = 0;
    std::int32_t submap = 0;
    double stamp = 0.0;
    if (!r.Value(&session) || !r.Value(&submap) || !r.Value(&stamp) ||
        !r.Bytes(d.keys.data() + i * key_dim, 4ull * key_dim) ||
        !r.Bytes(d.matrices.data() + i * d.matrix_size(), 4ull * d.matrix_size())) {
      return Status::Error(where + "truncated at entry " + std::to_string(i));
    }
    if (session >= session_count) {
      return Status::Error(where + "corrupt entry " + std::to_string(i) + " (session index " +
                           std::to_string(session) + " of " + std::to_string(session_count) + ")");
    }
    d.entries[i].session = sessions[session];
    d.entries[i].submap_id = submap;
    d.entries[i].stamp_s = stamp;
  }
  if (r.remaining() != 0) {
    return Status::Error(where + "corrupt: " + std::to_string(r.remaining()) +
                         " unexpected bytes after the last entry");
  }
  std::uint64_t checksum = 0;
  in.read(reinterpret_cast<char*>(&checksum), sizeof(checksum));
  if (!in) return Status::Error(where + "truncated (checksum missing)");
  if (checksum != r.hash()) {
    return Status::Error(where + "checksum mismatch (the file is corrupt)");
  }
  if (!AllFinite(d.keys) || !AllFinite(d.matrices)) {
    return Status::Error(where + "corrupt: non-finite descriptor values");
  }
  d.BuildTree();
  return db;
}

std::size_t DescriptorDatabase::size() const { return impl_->entries.size(); }
const DatabaseEntry& DescriptorDatabase::entry(std::size_t index) const {
  return impl_->entries.at(index);
}
DescriptorKind DescriptorDatabase::kind() const { return impl_->kind; }
int DescriptorDatabase::key_dim() const { return impl_->key_dim; }
const DescriptorDatabaseConfig& DescriptorDatabase::config() const { return impl_->config; }

}  // namespace core
}  // namespace multisession_mapper
