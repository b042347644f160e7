#include "multisession_mapper/tools/cli.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>

namespace multisession_mapper {
namespace tools {

bool ParseDouble(const std::string& text, double* value) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool ParseInt(const std::string& text, long long* value) {
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0') return false;
  *value = v;
  return true;
}

std::string FormatDuration(double seconds) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) return "--:--";
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%d:%02d", static_cast<int>(seconds) / 60,
                static_cast<int>(seconds) % 60);
  return buffer;
}

Progress::Progress(std::string label, std::size_t total, std::string unit, bool enabled)
    : label_(std::move(label)),
      total_(total),
      unit_(std::move(unit)),
      enabled_(enabled),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::seconds(1)) {}

double Progress::elapsed_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::Update(std::size_t done, const std::string& suffix) {
  done_ = done;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(250) && done < total_) return;
  last_draw_ = now;
  const double elapsed = elapsed_s();
  const double rate = elapsed > 0.0 ? done / elapsed : 0.0;
  const double eta = rate > 0.0 && total_ >= done ? (total_ - done) / rate : -1.0;
  const double percent = total_ > 0 ? 100.0 * done / total_ : 0.0;
  // A carriage return redraws in a terminal; in a log file every update is its own line.
  const bool tty = ::isatty(STDERR_FILENO);
  std::fprintf(stderr, "%s%s  %zu/%zu  %5.1f %%  %.1f %s/s  ETA %s  %s%s", tty ? "\r" : "",
               label_.c_str(), done, total_, percent, rate, unit_.c_str(),
               FormatDuration(eta).c_str(), suffix.c_str(), tty ? "\033[K" : "\n");
  std::fflush(stderr);
}

void Progress::Finish(const std::string& suffix) {
  if (!enabled_) return;
  const double elapsed = elapsed_s();
  std::fprintf(stderr, "%s%s  %zu %s in %s (%.1f %s/s)  %s\n",
               ::isatty(STDERR_FILENO) ? "\r\033[K" : "", label_.c_str(), done_, unit_.c_str(),
               FormatDuration(elapsed).c_str(), elapsed > 0.0 ? done_ / elapsed : 0.0,
               unit_.c_str(), suffix.c_str());
}

}  // namespace tools
}  // namespace multisession_mapper
