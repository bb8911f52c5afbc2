// models/nonlinear.cc — the default members of the nonlinear model interface and angle wrapping.
#include "models/nonlinear.h"

#include <cmath>

#include "kernel/check.h"

namespace ncosim::models {

double wrap_angle(double a) {
  constexpr double kPi = 3.14159265358979323846;
  double r = std::remainder(a, 2.0 * kPi);  // in [-pi, pi]
  if (r <= -kPi) r += 2.0 * kPi;
  return r;
}

Eigen::VectorXd angle_difference(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                                 const AngleMask& angles) {
  Eigen::VectorXd d = x - y;
  for (std::size_t i = 0; i < angles.size() && static_cast<Eigen::Index>(i) < d.size(); ++i)
    if (angles[i]) d(static_cast<Eigen::Index>(i)) = wrap_angle(d(static_cast<Eigen::Index>(i)));
  return d;
}

namespace {
const AngleMask& no_angles() {
  static const AngleMask none;
  return none;
}
}  // namespace

void NonlinearDynamics::f_many(Eigen::Ref<Eigen::MatrixXd> X, const Eigen::VectorXd& u,
                               std::int64_t k) const {
  Eigen::VectorXd x(X.cols()), out(X.cols());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    x = X.row(i).transpose();
    f(x, u, k, out);
    X.row(i) = out.transpose();
  }
}

const AngleMask& NonlinearDynamics::angles() const { return no_angles(); }

void NonlinearDynamics::f_noisy(const Eigen::VectorXd& x, const Eigen::VectorXd& u,
                                const Eigen::VectorXd& /*w*/, std::int64_t k,
                                Eigen::VectorXd& out) const {
  NCOSIM_CHECK(!noise_inside());  // such a kind implements f_noisy
  f(x, u, k, out);
}

void NonlinearDynamics::noise_jacobian(const Eigen::VectorXd& /*x*/, const Eigen::VectorXd& /*u*/,
                                       std::int64_t /*k*/, const Eigen::MatrixXd& Bw,
                                       Eigen::MatrixXd& G) const {
  NCOSIM_CHECK(!noise_inside());  // such a kind implements noise_jacobian
  G = Bw;
}

void MeasurementFunction::h_many(const Eigen::Ref<const Eigen::MatrixXd>& X, std::int64_t k,
                                 Eigen::Ref<Eigen::MatrixXd> Y) const {
  Eigen::VectorXd x(X.cols()), out(ny());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    x = X.row(i).transpose();
    h(x, k, out);
    Y.row(i) = out.transpose();
  }
}

const AngleMask& MeasurementFunction::angles() const { return no_angles(); }

}  // namespace ncosim::models
