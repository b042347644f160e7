// Counter-based random numbers for the simulator. Every random decision is derived from a key
// built from (seed, session, scan, ray, ...) with the SplitMix64 finaliser (Steele, Lea and
// Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014), so results do not
// depend on thread scheduling or on the order in which rays are traced.
#pragma once

#include <cstdint>

namespace multisession_mapper {
namespace sim {

/// SplitMix64 finaliser: a bijective 64-bit mix.
std::uint64_t Mix64(std::uint64_t x);

/// Key for a tuple of counters; different tuples give unrelated keys.
std::uint64_t MakeKey(std::uint64_t a, std::uint64_t b, std::uint64_t c = 0,
                      std::uint64_t d = 0);

/// Uniform number in [0, 1) from a key (53 random bits).
double UniformFromKey(std::uint64_t key);

/// Sequential generator (SplitMix64 stream) started from a key.
class CounterRng {
 public:
  explicit CounterRng(std::uint64_t key) : state_(key) {}

  std::uint64_t NextU64();
  /// Uniform in [0, 1).
  double Uniform();
  /// Uniform in [lo, hi).
  double Uniform(double lo, double hi);
  /// Integer uniform in [lo, hi] (inclusive).
  int UniformInt(int lo, int hi);
  /// Standard normal (Box-Muller).
  double Gaussian();
  bool Bernoulli(double p) { return Uniform() < p; }

 private:
  std::uint64_t state_;
};

}  // namespace sim
}  // namespace multisession_mapper
