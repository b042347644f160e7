#include "multisession_mapper/sim/counter_rng.h"

#include <cmath>

namespace multisession_mapper {
namespace sim {

std::uint64_t Mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

std::uint64_t MakeKey(std::uint64_t a, std::uint64_t b, std::uint64_t c, std::uint64_t d) {
  std::uint64_t h = Mix64(a);
  h = Mix64(h ^ b);
  h = Mix64(h ^ c);
  return Mix64(h ^ d);
}

double UniformFromKey(std::uint64_t key) {
  return static_cast<double>(Mix64(key) >> 11) * (1.0 / 9007199254740992.0);
}

std::uint64_t CounterRng::NextU64() {
  state_ += 0x9E3779B97F4A7C15ULL;
  std::uint64_t z = state_;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double CounterRng::Uniform() {
  return static_cast<double>(NextU64() >> 11) * (1.0 / 9007199254740992.0);
}

double CounterRng::Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }

int CounterRng::UniformInt(int lo, int hi) {
  if (hi <= lo) return lo;
  const std::uint64_t span = static_cast<std::uint64_t>(hi - lo) + 1;
  return lo + static_cast<int>(NextU64() % span);
}

double CounterRng::Gaussian() {
  // Box-Muller; 1 - u keeps the logarithm finite.
  const double u1 = 1.0 - Uniform();
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace sim
}  // namespace multisession_mapper
