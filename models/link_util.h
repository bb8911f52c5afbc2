// models/link_util.h — the samplers and checks shared by the link kinds (link.cc,
// markov_link.cc); internal to models/.
#pragma once

#include <algorithm>
#include <boost/random/uniform_01.hpp>
#include <cmath>
#include <cstddef>
#include <vector>

#include "kernel/check.h"
#include "kernel/rng.h"

namespace ncosim::models::link_util {

// Tolerance on "sums to 1" for laws given by the caller (rows of a transition matrix, ...).
constexpr double kSumTolerance = 1e-9;

inline double uniform(kernel::Rng& rng) {
  boost::random::uniform_01<double> u;
  return u(rng);
}

inline bool is_probability(double p) { return std::isfinite(p) && p >= 0.0 && p <= 1.0; }

inline double sum(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x;
  return s;
}

// Running sums of p: the sampler draws u ~ U[0, 1) and takes the first index whose
// cumulative value exceeds u; u beyond the last value means "none" (lost).
inline std::vector<double> cumulative(const std::vector<double>& p) {
  std::vector<double> c(p.size());
  double s = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    s += p[i];
    c[i] = s;
  }
  return c;
}

// Cumulative law of a distribution that sums to 1 (within kSumTolerance): rounding must
// never leave a gap above the last value, so every entry from the last index with
// positive probability on is set to exactly 1.
inline std::vector<double> cumulative_law(const std::vector<double>& p) {
  std::vector<double> c = cumulative(p);
  std::size_t last = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p[i] > 0.0) last = i;
  }
  for (std::size_t i = last; i < c.size(); ++i) c[i] = 1.0;
  return c;
}

// Index of the first cumulative value > u in [first, last): last - first when none is.
inline std::size_t sample(const double* first, const double* last, double u) {
  return static_cast<std::size_t>(std::upper_bound(first, last, u) - first);
}

inline void check_max_delay(int max_delay) { NCOSIM_CHECK(max_delay >= 0); }

}  // namespace ncosim::models::link_util
