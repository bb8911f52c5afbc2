// models/noise.h — standard normal vectors from a run's Boost.Random stream (platform-independent
// draws: the same numbers on every machine for the same stream).
#pragma once

#include <Eigen/Dense>
#include <boost/random/normal_distribution.hpp>

#include "kernel/rng.h"

namespace ncosim::models {

// out(i) ~ N(0, 1) independent, drawn in index order.
inline void draw_standard_normal(kernel::Rng& rng, Eigen::VectorXd& out) {
  boost::random::normal_distribution<double> normal(0.0, 1.0);
  for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = normal(rng);
}

}  // namespace ncosim::models
