// atan2 by a polynomial, for the per-point angle computations of the hot loops (the
// in-session visibility check evaluates one per map voxel per check, about 10^5 per scan;
// std::atan2 was 7 % of the whole single-session pipeline in a perf profile of 600 campus
// scans). Maximum error 2.5e-7 rad (1.4e-5 deg, test/fast_atan2_test.cpp), far below the
// 0.4 deg azimuth bins and 0.1 deg elevation gates it feeds.
#pragma once

#include <cmath>

namespace multisession_mapper {
namespace core {

/// atan(t) for t in [-1, 1]: t * P(t^2), P of degree 6 fitted to atan(t)/t on [0, 1] by
/// iteratively reweighted least squares towards the minimax error (scripted in numpy; the
/// coefficients are ours, not a published table). In double (AtanUnit) and in float
/// (AtanUnitF, for loops the compiler vectorises, 4 lanes: within ~3.5e-7 rad of atan(t), the
/// polynomial's error plus float rounding); each coefficient converted to float is the
/// nearest float to its decimal.
template <typename T>
inline T AtanUnitOf(T t) {
  const T s = t * t;
  return t * (T(0.9999961128) +
              s * (T(-0.3331737241) +
                   s * (T(0.1980785709) +
                        s * (T(-0.1323350635) +
                             s * (T(0.0796267560) +
                                  s * (T(-0.0336069497) + s * T(0.0068127093)))))));
}
inline double AtanUnit(double t) { return AtanUnitOf(t); }
inline float AtanUnitF(float t) { return AtanUnitOf(t); }

/// atan2(y, x) in (-pi, pi], within 2.5e-7 rad of std::atan2; 0 for (0, 0).
inline double FastAtan2(double y, double x) {
  const double ax = std::abs(x);
  const double ay = std::abs(y);
  if (ax == 0.0 && ay == 0.0) return 0.0;
  // Reduce to the octant |t| <= 1, then unfold.
  double angle = ay <= ax ? AtanUnit(ay / ax) : M_PI_2 - AtanUnit(ax / ay);
  if (x < 0.0) angle = M_PI - angle;
  return y < 0.0 ? -angle : angle;
}

}  // namespace core
}  // namespace multisession_mapper
