// sim/run/run_recorder.cc — what one run measures.
#include "sim/run/run_recorder.h"

#include <algorithm>
#include <cmath>

namespace ncosim::sim {

namespace {

constexpr double kDivergence = 1e150;
constexpr double kPrecisionLimit = 1e10;

}  // namespace

RunRecorder::RunRecorder(const Scenario& sc, const Estimators& estimators,
                         std::vector<TraceRow>* trace, ErrorCurve* curve)
    : sc_(sc),
      estimators_(estimators),
      trace_(trace),
      curve_(curve),
      warmup_(sc.run.warmup),
      block_length_((sc.run.periods - sc.run.warmup) / kErrorBlocks),
      mode_count_(sc.model.mode_count()),
      arrivals_(sc.model.sensors.size(), 0),
      err_(sc.model.plant.n()),
      chol_(static_cast<std::size_t>(sc.model.plant.n() * sc.model.plant.n())),
      whitened_(sc.model.plant.n()),
      nis_start_(sc.estimators.size()) {
  const Eigen::Index n = sc.model.plant.n();
  int max_ext_blocks = 1;
  for (const auto& e : sc.estimators) {
    const auto ext = e.design->extended_size();
    if (ext > 0) max_ext_blocks = std::max<int>(max_ext_blocks, static_cast<int>(ext / n));
    EstimatorRunMetrics m;
    m.sse_state.assign(static_cast<std::size_t>(n), 0.0);
    if (block_length_ > 0) m.sse_blocks.assign(static_cast<std::size_t>(kErrorBlocks), 0.0);
    if (mode_count_ > 0 && mode_count_ <= kMaxConfusionModes) {
      m.confusion.assign(static_cast<std::size_t>(mode_count_ * mode_count_), 0);
    }
    metrics_.push_back(std::move(m));
  }
  sensors_.sensor_taken.assign(sc.model.sensors.size(), 0);
  sensors_.sensor_sent.assign(sc.model.sensors.size(), 0);
  for (const auto& sm : sc.model.sensors)
    sensors_.sensor_virtual_sse.emplace_back(static_cast<std::size_t>(sm.spec.ny()), 0.0);
  // x[-j] = x0: the plant rests at x0 before t = 0.
  history_.assign(static_cast<std::size_t>(max_ext_blocks), sc.model.plant.x0);
}

void RunRecorder::on_state(std::int64_t k, const Eigen::VectorXd& x) {
  if (k > 0) {
    std::rotate(history_.rbegin(), history_.rbegin() + 1, history_.rend());
    history_.front() = x;
  } else {
    std::fill(history_.begin(), history_.end(), x);
  }
}

void RunRecorder::on_sample(std::size_t s, std::int64_t k, bool sent,
                            const Eigen::Ref<const Eigen::VectorXd>& sample,
                            const Eigen::VectorXd* held) {
  if (k < warmup_) return;
  // The sensors' counts are the same for every estimator: kept once, copied by finish().
  ++sensors_.samples_taken;
  ++sensors_.sensor_taken[s];
  if (sent) {
    ++sensors_.sensor_sent[s];
    return;
  }
  if (held == nullptr) return;  // a policy that keeps no held value
  for (Eigen::Index i = 0; i < sample.size(); ++i) {
    const double d = (*held)(i)-sample(i);
    sensors_.sensor_virtual_sse[s][static_cast<std::size_t>(i)] += d * d;
  }
}

void RunRecorder::on_period(std::int64_t k, const Eigen::VectorXd& x, int true_mode,
                            const Eigen::VectorXd& u, double reference) {
  if (trace_ != nullptr) trace_row(k, x, true_mode, u, reference);
  std::fill(arrivals_.begin(), arrivals_.end(), 0);
  // |x| > 1e10: x - xhat has lost 10 of its 16 significant digits to rounding (an unstable
  // plant left without feedback or re-centring); the errors are no longer trustworthy.
  if (!precision_lost_ && x.cwiseAbs().maxCoeff() > kPrecisionLimit) precision_lost_ = true;
  if (k == warmup_ - 1) {  // the innovations counted from here on are those of k >= warmup
    for (std::size_t e = 0; e < estimators_.size(); ++e) {
      if (const auto* in = estimators_[e]->innovations()) nis_start_[e] = *in;
    }
  }
  const bool scored = k >= warmup_;
  if (!scored && curve_ == nullptr) return;
  const Eigen::Index n = x.size();
  // The error block of period k (EstimatorRunMetrics::sse_blocks; past the last: none).
  const auto block =
      static_cast<std::size_t>(scored && block_length_ > 0 ? (k - warmup_) / block_length_ : 0);
  for (std::size_t e = 0; e < estimators_.size(); ++e) {
    EstimatorRunMetrics& m = metrics_[e];
    if (m.diverged && curve_ == nullptr) continue;
    err_ = x - estimators_[e]->state();
    // The error curve takes every period from k = 0 (the start-up transient is the point) and
    // every estimator, diverged or not (a squared error that overflows makes its cell non-finite:
    // empty in the file).
    if (curve_ != nullptr) curve_->add(k, e, err_.data());
    if (!scored || m.diverged) continue;
    const double e2 = err_.squaredNorm();
    double e2_ext = e2;
    if (const Eigen::VectorXd* xb = estimators_[e]->extended()) {
      for (Eigen::Index b = 1; b < xb->size() / n; ++b) {
        e2_ext += (history_[static_cast<std::size_t>(b)] - xb->segment(b * n, n)).squaredNorm();
      }
    }
    if (!std::isfinite(e2_ext) || e2_ext > kDivergence) {
      m.diverged = true;
      continue;
    }
    m.sse += e2;
    if (block < m.sse_blocks.size()) m.sse_blocks[block] += e2;
    m.sse_ext += e2_ext;
    for (Eigen::Index i = 0; i < n; ++i)
      m.sse_state[static_cast<std::size_t>(i)] += err_(i) * err_(i);
    ++m.count;
    score_consistency(m, *estimators_[e], n);
  }
  if (scored && k >= 1) score_modes(true_mode);
}

void RunRecorder::trace_row(std::int64_t k, const Eigen::VectorXd& x, int true_mode,
                            const Eigen::VectorXd& u, double reference) {
  const Eigen::Index n = x.size();
  TraceRow row;
  row.period = k;
  row.x.assign(x.data(), x.data() + n);
  for (const auto& e : estimators_) {
    const auto xh = e->state();
    row.xhat.emplace_back(xh.data(), xh.data() + n);
  }
  row.arrivals = arrivals_;
  row.mode = true_mode;
  for (const auto& e : estimators_) row.mode_hat.push_back(e->mode().value_or(-1));
  row.u.assign(u.data(), u.data() + u.size());
  for (const auto& sm : sc_.model.sensors) {
    const Eigen::VectorXd y = sm.spec.C * x;
    row.y.insert(row.y.end(), y.data(), y.data() + y.size());
  }
  row.reference = reference;
  trace_->push_back(std::move(row));
}

// NEES of period k: e' P^-1 e = |L^-1 e|^2 with P = L L' the state block of the estimator's own
// covariance; a P that is not positive definite (e.g. P0 = 0 before the first packet) is skipped.
// (Cholesky by hand on the leading n x n block: Eigen's dynamic LLT cost ~600 instructions for
// n = 2, about 7 % of the flagship's whole run.)
void RunRecorder::score_consistency(EstimatorRunMetrics& m, const est::Estimator& e,
                                    Eigen::Index n) {
  const Eigen::MatrixXd* P = e.covariance();
  if (P == nullptr || P->rows() < n || P->cols() < n) return;
  const double* p = P->data();
  const Eigen::Index ld = P->rows();
  double* L = chol_.data();  // column-major n x n, lower triangle
  double* z = whitened_.data();
  double nees = 0.0;
  for (Eigen::Index j = 0; j < n; ++j) {
    double d = p[j * ld + j];
    for (Eigen::Index k = 0; k < j; ++k) d -= L[k * n + j] * L[k * n + j];
    if (!(d > 0.0)) return;  // not positive definite (or NaN): no NEES this period
    const double ljj = std::sqrt(d);
    L[j * n + j] = ljj;
    for (Eigen::Index i = j + 1; i < n; ++i) {
      double v = p[j * ld + i];
      for (Eigen::Index k = 0; k < j; ++k) v -= L[k * n + i] * L[k * n + j];
      L[j * n + i] = v / ljj;
    }
    double r = err_(j);  // forward substitution of L z = e, row j
    for (Eigen::Index k = 0; k < j; ++k) r -= L[k * n + j] * z[k];
    z[j] = r / ljj;
    nees += z[j] * z[j];
  }
  if (!std::isfinite(nees)) return;
  m.nees += nees;
  ++m.nees_count;
}

// Mode detection (Moayedi et al. eq. 27a-b): after the update of period k >= 1, each mode
// estimator's estimate of theta[k-1] against the true one.
void RunRecorder::score_modes(int true_mode) {
  if (mode_count_ == 0 || true_mode < 0) return;
  for (std::size_t e = 0; e < estimators_.size(); ++e) {
    const std::optional<int> est = estimators_[e]->mode();
    if (!est) continue;
    EstimatorRunMetrics& m = metrics_[e];
    ++m.mode_count;
    if (*est != true_mode) ++m.mode_errors;
    if (!m.confusion.empty() && *est >= 0 && *est < mode_count_) {
      ++m.confusion[static_cast<std::size_t>(true_mode * mode_count_ + *est)];
    }
  }
}

RunMetrics RunRecorder::finish() {
  for (std::size_t e = 0; e < estimators_.size(); ++e) {
    metrics_[e].samples_taken = sensors_.samples_taken;
    metrics_[e].sensor_taken = sensors_.sensor_taken;
    metrics_[e].sensor_sent = sensors_.sensor_sent;
    metrics_[e].sensor_virtual_sse = sensors_.sensor_virtual_sse;
    metrics_[e].status = estimators_[e]->status();
    if (const auto* c = estimators_[e]->counters()) metrics_[e].counters = *c;
    if (const auto* in = estimators_[e]->innovations(); in != nullptr && !metrics_[e].diverged) {
      metrics_[e].nis = in->nis - nis_start_[e].nis;
      metrics_[e].nis_dof = in->dof - nis_start_[e].dof;
      metrics_[e].nis_count = in->updates - nis_start_[e].updates;
    }
    if (precision_lost_ && metrics_[e].status == "ok") metrics_[e].status = "precision_lost";
  }
  return std::move(metrics_);
}

}  // namespace ncosim::sim
