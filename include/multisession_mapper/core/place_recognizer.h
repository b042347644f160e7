// Per-scan place recognition while a session is mapped (reference paper, section V): every
// scan gets a descriptor; when a stored map exists, the descriptor is queried against the
// map's database (nearest history scan, "no match" beyond d_alpha) and the answer is kept for
// the per-submap vote and for the log place_recognition/<session>.csv (docs/map_format.md).
// At the end of the session the new descriptors extend the database.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "multisession_mapper/core/descriptor_database.h"
#include "multisession_mapper/core/place_descriptor_extractor.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap_voting.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct PlaceRecognizerConfig {
  PlaceDescriptorExtractorConfig descriptor;
  DescriptorDatabaseConfig database;
  /// Neighbours written per query in the log (top_k column).
  int log_neighbours = 5;

  Status Validate() const;
};

/// One scan's query against the history database.
struct ScanQuery {
  double stamp_s = 0.0;
  std::uint32_t submap_id = 0;
  DatabaseQueryResult result;
};

class PlaceRecognizer {
 public:
  /// `history` may be null (first session: descriptors only). When given, it must match the
  /// configured descriptor kind and dimension.
  static StatusOr<PlaceRecognizer> Create(const PlaceRecognizerConfig& config,
                                          const std::string& session,
                                          std::shared_ptr<const DescriptorDatabase> history);

  /// Describes one de-skewed scan of submap `submap_id` and queries the history.
  Status AddScan(const LidarScan& deskewed_scan, std::uint32_t submap_id);

  /// Votes of the scans of `submap_id` (for SubmapVoting).
  std::vector<ScanVote> VotesOf(std::uint32_t submap_id) const;

  /// The log of all queries (empty when there was no history to query).
  std::string QueriesCsv() const;

  /// Inserts this session's scans (descriptor, session, stamp, submap id) into `database`:
  /// the map's database when merging, or a new one (NewDatabase) for the first session.
  Status AppendTo(DescriptorDatabase* database) const;
  /// As above, leaving out the scans of `skip_submaps` (submaps fused into history submaps:
  /// the history's descriptors already describe their place).
  Status AppendTo(DescriptorDatabase* database, const std::set<std::uint32_t>& skip_submaps) const;
  /// The history database queried (null for the first session).
  const std::shared_ptr<const DescriptorDatabase>& history() const { return history_; }
  /// An empty database of the configured descriptor kind.
  StatusOr<DescriptorDatabase> NewDatabase() const;

  const std::vector<double>& descriptor_ms() const { return descriptor_ms_; }
  const std::vector<double>& query_ms() const { return query_ms_; }
  std::size_t num_scans() const { return entries_.size(); }
  /// The queries of this session so far, in scan order (empty when there is no history);
  /// neighbour indices refer to history()->entry().
  const std::vector<ScanQuery>& queries() const { return queries_; }

 private:
  PlaceRecognizer(const PlaceRecognizerConfig& config, const std::string& session,
                  PlaceDescriptorExtractor extractor,
                  std::shared_ptr<const DescriptorDatabase> history)
      : config_(config),
        session_(session),
        extractor_(std::move(extractor)),
        history_(std::move(history)) {}

  PlaceRecognizerConfig config_;
  std::string session_;
  PlaceDescriptorExtractor extractor_;
  std::shared_ptr<const DescriptorDatabase> history_;
  std::vector<DatabaseEntry> entries_;
  std::vector<PlaceDescriptor> descriptors_;
  std::vector<ScanQuery> queries_;
  std::vector<double> descriptor_ms_;
  std::vector<double> query_ms_;
};

}  // namespace core
}  // namespace multisession_mapper
