// models/sensor_process.cc — one sensor of one run.
#include "models/sensor_process.h"

#include <algorithm>
#include <boost/random/uniform_real_distribution.hpp>
#include <cmath>

#include "models/noise.h"

namespace ncosim::models {

namespace {

// Unit-variance noise: standard normal, or uniform on [-sqrt 3, sqrt 3].
void draw_noise(kernel::Rng& rng, SensorSpec::Noise kind, Eigen::VectorXd& out) {
  if (kind == SensorSpec::Noise::kGaussian) {
    draw_standard_normal(rng, out);
    return;
  }
  boost::random::uniform_real_distribution<double> uni(-std::sqrt(3.0), std::sqrt(3.0));
  for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = uni(rng);
}

}  // namespace

SensorProcess::SensorProcess(const SensorSpec& spec, int index, std::uint64_t seed,
                             std::uint64_t run)
    : spec_(spec),
      index_(index),
      rng_(kernel::make_stream(
          seed, run,
          kernel::stream_id(kernel::StreamKind::kSensor, static_cast<std::uint64_t>(index)))),
      r_sqrt_(psd_sqrt(spec.R)),
      noise_(spec.ny()),
      stamps_(static_cast<std::size_t>(spec.buffer) + 1, 0),
      values_(Eigen::MatrixXd::Zero(spec.ny(), spec.buffer + 1)),
      policy_(spec.policy->instantiate()) {
  if (spec.fresh_resend_noise) clean_ = Eigen::MatrixXd::Zero(spec.ny(), spec.buffer + 1);
}

bool SensorProcess::sample(std::int64_t k, const Eigen::VectorXd& x) {
  draw_noise(rng_, spec_.noise, noise_);
  head_ = (head_ + 1) % (spec_.buffer + 1);
  filled_ = std::min(filled_ + 1, spec_.buffer + 1);
  stamps_[static_cast<std::size_t>(head_)] = k;
  values_.col(head_).noalias() = spec_.C * x;
  if (spec_.fresh_resend_noise) clean_.col(head_) = values_.col(head_);
  values_.col(head_).noalias() += r_sqrt_ * noise_;
  return policy_->decide(values_.col(head_));
}

void SensorProcess::redraw_newest(const Eigen::VectorXd& x) {
  draw_noise(rng_, spec_.noise, noise_);
  values_.col(head_).noalias() = spec_.C * x;
  values_.col(head_).noalias() += r_sqrt_ * noise_;
}

void SensorProcess::pack(Packet& p, std::int64_t k, bool independent_copy) {
  const Eigen::Index ny = spec_.ny();
  const int slots = spec_.buffer + 1;
  p.sensor = index_;
  p.send_period = k;
  // A re-sent sample with a fresh noise draw is a new measurement, like an independent copy.
  p.independent_copy = independent_copy || (spec_.fresh_resend_noise && filled_ > 1);
  p.count = filled_;
  p.stamps.resize(static_cast<std::size_t>(filled_));
  p.values.resize(ny * filled_);
  for (int i = 0; i < filled_; ++i) {
    const int slot = (head_ - i + slots) % slots;
    p.stamps[static_cast<std::size_t>(i)] = stamps_[static_cast<std::size_t>(slot)];
    if (spec_.fresh_resend_noise && i > 0) {  // resend_noise = "fresh": a new draw per re-send
      draw_standard_normal(rng_, noise_);
      p.values.segment(i * ny, ny) = clean_.col(slot);
      p.values.segment(i * ny, ny).noalias() += r_sqrt_ * noise_;
    } else {
      p.values.segment(i * ny, ny) = values_.col(slot);
    }
  }
}

}  // namespace ncosim::models
