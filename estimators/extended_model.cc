// estimators/extended_model.cc — delay-extended matrices and design-model pattern probabilities.
#include "estimators/extended_model.h"

#include <bit>

#include "kernel/check.h"

namespace ncosim::est {

Eigen::VectorXd ExtendedModel::row_mask(std::uint64_t pattern) const {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(nmb);
  for (int j = 0; j < fictitious_count(); ++j) {
    if ((pattern >> j) & 1U) m.segment(fict[j].row, fict[j].rows).setOnes();
  }
  return m;
}

int ExtendedModel::real_sensors(std::uint64_t pattern) const {
  int count = 0;
  const std::uint64_t block = (std::uint64_t{1} << (dbar + 1)) - 1;
  for (int i = 0; i < sensors; ++i) {
    if ((pattern >> (i * (dbar + 1))) & block) ++count;
  }
  return count;
}

ExtendedModel build_extended(const Model& model, int dbar) {
  ExtendedModel e;
  const auto& p = model.plant;
  e.dbar = dbar;
  e.n = p.n();
  e.nb = e.n * (dbar + 1);
  e.nu = p.nu();
  e.nw = p.nw();
  e.sensors = static_cast<int>(model.sensors.size());
  e.A = Eigen::MatrixXd::Zero(e.nb, e.nb);
  e.A.topLeftCorner(e.n, e.n) = p.A;
  for (int b = 1; b <= dbar; ++b) e.A.block(b * e.n, (b - 1) * e.n, e.n, e.n).setIdentity();
  e.Q = Eigen::MatrixXd::Zero(e.nb, e.nb);
  e.Q.topLeftCorner(e.n, e.n) = p.Bw * p.W * p.Bw.transpose();
  Eigen::Index rows = 0;
  for (const auto& s : model.sensors) rows += s.spec.ny() * (dbar + 1);
  e.nmb = rows;
  e.C = Eigen::MatrixXd::Zero(rows, e.nb);
  e.V = Eigen::MatrixXd::Zero(rows, rows);
  Eigen::Index r = 0;
  for (int i = 0; i < e.sensors; ++i) {
    const auto& s = model.sensors[i].spec;
    for (int d = 0; d <= dbar; ++d) {
      e.fict.push_back({i, d, r, s.ny()});
      e.C.block(r, d * e.n, s.ny(), e.n) = s.C;
      e.V.block(r, r, s.ny(), s.ny()) = s.R;
      r += s.ny();
    }
  }
  return e;
}

std::vector<double> pattern_probabilities(const Model& model, const ExtendedModel& ext) {
  const int nf = ext.fictitious_count();
  NCOSIM_CHECK(nf <= 24);
  const int width = ext.dbar + 1;
  std::vector<double> joint{1.0};  // over the sensors handled so far
  int bits_so_far = 0;
  for (int i = 0; i < ext.sensors; ++i) {
    const auto& sm = model.sensors[i];
    const std::vector<double> q = sm.delay_pmf(ext.dbar);
    const double rate = 1.0 / sm.spec.every;  // share of periods with a sample
    // Packet sent d periods ago arrives now with probability rate * q[d]; it carries the
    // samples of delays d, d + every, ..., d + buffer * every (those within dbar).
    std::vector<double> local(std::size_t{1} << width, 0.0);
    for (std::uint32_t arrived = 0; arrived < (1U << width); ++arrived) {
      double prob = 1.0;
      std::uint32_t mask = 0;
      for (int d = 0; d < width; ++d) {
        const double pd = rate * q[d];
        if ((arrived >> d) & 1U) {
          prob *= pd;
          for (int c = 0; c <= sm.spec.buffer; ++c) {
            const int delay = d + c * sm.spec.every;
            if (delay <= ext.dbar) mask |= 1U << delay;
          }
        } else {
          prob *= 1.0 - pd;
        }
      }
      local[mask] += prob;
    }
    std::vector<double> next(joint.size() << width, 0.0);
    for (std::size_t a = 0; a < joint.size(); ++a) {
      if (joint[a] == 0.0) continue;
      for (std::size_t b = 0; b < local.size(); ++b) {
        next[a | (b << bits_so_far)] += joint[a] * local[b];
      }
    }
    joint.swap(next);
    bits_so_far += width;
  }
  return joint;
}

Eigen::MatrixXd stein_operator(const Eigen::MatrixXd& A, double p0) {
  const Eigen::Index n = A.rows();
  Eigen::MatrixXd K(n * n, n * n);
  // vec(A X A') = (A ⊗ A) vec(X), column-major vec.
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) K.block(i * n, j * n, n, n) = A(i, j) * A;
  }
  Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n * n, n * n);
  return (I - p0 * K).inverse();
}

Eigen::MatrixXd stein_sum(const Eigen::MatrixXd& stein, const Eigen::MatrixXd& X) {
  const Eigen::Index n = X.rows();
  Eigen::VectorXd v = stein * Eigen::Map<const Eigen::VectorXd>(X.data(), n * n);
  Eigen::MatrixXd S = Eigen::Map<Eigen::MatrixXd>(v.data(), n, n);
  return 0.5 * (S + S.transpose());
}

}  // namespace ncosim::est
