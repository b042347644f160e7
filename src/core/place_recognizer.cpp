#include "multisession_mapper/core/place_recognizer.h"

#include <chrono>
#include <iomanip>
#include <sstream>

namespace multisession_mapper {
namespace core {
namespace {
double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}
}  // namespace

Status PlaceRecognizerConfig::Validate() const {
  Status s = descriptor.Validate();
  if (!s.ok()) return s;
  s = database.Validate();
  if (!s.ok()) return s;
  if (log_neighbours < 1) return Status::Error("place_recognition.log_neighbours must be >= 1");
  return Status::Ok();
}

StatusOr<PlaceRecognizer> PlaceRecognizer::Create(
    const PlaceRecognizerConfig& config, const std::string& session,
    std::shared_ptr<const DescriptorDatabase> history) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  StatusOr<PlaceDescriptorExtractor> extractor = PlaceDescriptorExtractor::Create(config.descriptor);
  if (!extractor.ok()) return extractor.status();
  if (history && (history->kind() != extractor.value().kind() ||
                  history->key_dim() != extractor.value().key_dim())) {
    return Status::Error(std::string("the map's place database holds ") +
                         DescriptorKindName(history->kind()) + " descriptors of dimension " +
                         std::to_string(history->key_dim()) + ", the configuration asks for " +
                         DescriptorKindName(extractor.value().kind()) + " of dimension " +
                         std::to_string(extractor.value().key_dim()));
  }
  return PlaceRecognizer(config, session, std::move(extractor.value()), std::move(history));
}

Status PlaceRecognizer::AddScan(const LidarScan& deskewed_scan, std::uint32_t submap_id) {
  auto start = std::chrono::steady_clock::now();
  PlaceDescriptor descriptor = extractor_.Compute(deskewed_scan);
  descriptor_ms_.push_back(MsSince(start));
  DatabaseEntry entry;
  entry.session = session_;
  entry.stamp_s = deskewed_scan.stamp_s;
  entry.submap_id = static_cast<int>(submap_id);
  if (history_ && history_->size() > 0) {
    start = std::chrono::steady_clock::now();
    StatusOr<DatabaseQueryResult> result = history_->Query(descriptor, config_.log_neighbours);
    query_ms_.push_back(MsSince(start));
    if (!result.ok()) return result.status();
    ScanQuery query;
    query.stamp_s = entry.stamp_s;
    query.submap_id = submap_id;
    query.result = std::move(result.value());
    queries_.push_back(std::move(query));
  }
  entries_.push_back(entry);
  descriptors_.push_back(std::move(descriptor));
  return Status::Ok();
}

std::vector<ScanVote> PlaceRecognizer::VotesOf(std::uint32_t submap_id) const {
  std::vector<ScanVote> votes;
  for (const ScanQuery& q : queries_) {
    if (q.submap_id != submap_id) continue;
    ScanVote vote;
    vote.matched = q.result.matched && !q.result.neighbors.empty();
    if (vote.matched) {
      const DatabaseEntry& nearest = history_->entry(q.result.neighbors.front().index);
      vote.history.session = nearest.session;
      vote.history.submap_id = nearest.submap_id;
    }
    votes.push_back(vote);
  }
  return votes;
}

std::string PlaceRecognizer::QueriesCsv() const {
  if (queries_.empty()) return "";
  std::ostringstream out;
  out << "stamp,submap,matched,history_session,history_stamp,distance,top_k\n";
  out << std::fixed;
  for (const ScanQuery& q : queries_) {
    out << std::setprecision(6) << q.stamp_s << ',' << q.submap_id << ','
        << (q.result.matched ? 1 : 0) << ',';
    if (q.result.neighbors.empty()) {
      out << ",,";
    } else {
      const DatabaseNeighbor& nearest = q.result.neighbors.front();
      const DatabaseEntry& e = history_->entry(nearest.index);
      out << e.session << ',' << std::setprecision(6) << e.stamp_s << ','
          << std::setprecision(6) << nearest.distance;
    }
    out << ',';
    for (std::size_t i = 0; i < q.result.neighbors.size(); ++i) {
      const DatabaseNeighbor& n = q.result.neighbors[i];
      const DatabaseEntry& e = history_->entry(n.index);
      out << (i ? ";" : "") << e.session << ':' << std::setprecision(6) << e.stamp_s << ':'
          << n.distance;
    }
    out << '\n';
  }
  return out.str();
}

StatusOr<DescriptorDatabase> PlaceRecognizer::NewDatabase() const {
  return extractor_.CreateDatabase(config_.database);
}

Status PlaceRecognizer::AppendTo(DescriptorDatabase* database) const {
  return AppendTo(database, {});
}

Status PlaceRecognizer::AppendTo(DescriptorDatabase* database,
                                 const std::set<std::uint32_t>& skip_submaps) const {
  std::vector<DatabaseEntry> entries;
  std::vector<PlaceDescriptor> descriptors;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (skip_submaps.count(static_cast<std::uint32_t>(entries_[i].submap_id))) continue;
    entries.push_back(entries_[i]);
    descriptors.push_back(descriptors_[i]);
  }
  if (entries.empty()) return Status::Ok();
  return database->Insert(entries, descriptors);
}

}  // namespace core
}  // namespace multisession_mapper
