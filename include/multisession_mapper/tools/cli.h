// Small helpers shared by the command-line tools: strict number parsing and a progress line
// with rate and ETA on stderr. Tools only; the core never prints.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>

namespace multisession_mapper {
namespace tools {

/// Whole-string parse; false on trailing characters, empty input or a non-finite value.
bool ParseDouble(const std::string& text, double* value);
bool ParseInt(const std::string& text, long long* value);

/// "m:ss" for a duration in seconds, "--:--" when unknown.
std::string FormatDuration(double seconds);

/// Progress line on stderr, redrawn at most a few times per second:
///   "<label>  1234/5000  24.7 %  312.0 scans/s  ETA 0:12"
class Progress {
 public:
  Progress(std::string label, std::size_t total, std::string unit, bool enabled = true);
  void Update(std::size_t done, const std::string& suffix = "");
  /// Final line with the total time.
  void Finish(const std::string& suffix = "");
  double elapsed_s() const;

 private:
  std::string label_;
  std::size_t total_;
  std::string unit_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  std::size_t done_ = 0;
};

}  // namespace tools
}  // namespace multisession_mapper
