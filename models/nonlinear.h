// models/nonlinear.h — the interface of nonlinear plant and sensor models, shared by every
// nonlinear kind (built in, written as expressions in the scenario file, or plugged in from C++
// or Python), the true plant and sensors of a run, the nonlinear estimators and the posterior
// Cramér–Rao bound:
//   plant:  x[k+1] = f(x[k], u[k], k) + Bw w[k],  w ~ N(0, W)   (Bw, W: the LinearPlant's)
//           or, for a kind whose noise enters inside f, x[k+1] = f(x[k], u[k], w[k], k);
//   sensor: y[k]   = h(x[k], k) + v[k],            v ~ N(0, R)   (R: the SensorSpec's).
// A nonlinear plant is still handed around as a models::LinearPlant (models/plant.h): its
// `nonlinear` member points to f, its A and Bu are f's Jacobians at (x0, 0, k = 0) (what tools
// that need only sizes or a nominal linearisation read), Bw, W and x0 mean what they mean for a
// linear plant. A nonlinear sensor's SensorSpec::h points to h and its C is h's Jacobian at x0.
// Estimators that need a linear model refuse a nonlinear one when the scenario is read.
// Implementations are immutable after construction and thread-safe (shared by every run).
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

namespace ncosim::models {

// Which components are angles in radians (true): differences of them (innovations, estimation
// errors) are wrapped to (-pi, pi] and their means are circular. Empty: none.
using AngleMask = std::vector<bool>;

// x - y with the components of `angles` wrapped to (-pi, pi].
Eigen::VectorXd angle_difference(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                                 const AngleMask& angles);
// a wrapped to (-pi, pi].
double wrap_angle(double a);

class NonlinearDynamics {
 public:
  virtual ~NonlinearDynamics() = default;
  virtual Eigen::Index n() const = 0;   // states
  virtual Eigen::Index nu() const = 0;  // inputs (may be 0)
  // out = f(x, u, k): the state of period k + 1 before the additive noise (out is sized n).
  virtual void f(const Eigen::VectorXd& x, const Eigen::VectorXd& u, std::int64_t k,
                 Eigen::VectorXd& out) const = 0;
  // F = df/dx at (x, u, k), n x n: exact (symbolic or by hand), never finite differences, for
  // the built-in and expression kinds.
  virtual void jacobian(const Eigen::VectorXd& x, const Eigen::VectorXd& u, std::int64_t k,
                        Eigen::MatrixXd& F) const = 0;
  // Many states at once, in place: row i of X (N x n, column-major, so each component is one
  // contiguous array: structure of arrays) becomes f(X.row(i)', u, k)'. The default loops over
  // f; kinds that care about particle filters override it with vector passes.
  virtual void f_many(Eigen::Ref<Eigen::MatrixXd> X, const Eigen::VectorXd& u,
                      std::int64_t k) const;
  virtual const AngleMask& angles() const;  // default: none

  // Noise inside f (false by default: additive Bw w). A kind that returns true implements
  // f_noisy and noise_jacobian; f(x, u, k) is then f(x, u, 0, k).
  virtual bool noise_inside() const { return false; }
  // out = f(x, u, w, k) (w: nw entries, the plant's W is its covariance).
  virtual void f_noisy(const Eigen::VectorXd& x, const Eigen::VectorXd& u, const Eigen::VectorXd& w,
                       std::int64_t k, Eigen::VectorXd& out) const;
  // G = df/dw at (x, u, w = 0, k), n x nw (the additive case: Bw, which the caller passes).
  virtual void noise_jacobian(const Eigen::VectorXd& x, const Eigen::VectorXd& u, std::int64_t k,
                              const Eigen::MatrixXd& Bw, Eigen::MatrixXd& G) const;
};

class MeasurementFunction {
 public:
  virtual ~MeasurementFunction() = default;
  virtual Eigen::Index n() const = 0;   // states it reads
  virtual Eigen::Index ny() const = 0;  // outputs
  // out = h(x, k) (out is sized ny).
  virtual void h(const Eigen::VectorXd& x, std::int64_t k, Eigen::VectorXd& out) const = 0;
  // H = dh/dx at (x, k), ny x n, exact as for NonlinearDynamics::jacobian.
  virtual void jacobian(const Eigen::VectorXd& x, std::int64_t k, Eigen::MatrixXd& H) const = 0;
  // Many states at once: row i of Y (N x ny) = h(X.row(i)', k)'. Default: loops over h.
  virtual void h_many(const Eigen::Ref<const Eigen::MatrixXd>& X, std::int64_t k,
                      Eigen::Ref<Eigen::MatrixXd> Y) const;
  virtual const AngleMask& angles() const;  // which outputs are angles; default: none
};

}  // namespace ncosim::models
