// models/plant_process.cc — the built-in plant processes.
#include "models/plant_process.h"

#include <boost/random/uniform_01.hpp>

#include "models/noise.h"

namespace ncosim::models {

namespace {

// dst = alpha M v (add = false) or dst += alpha M v (add = true), with the bits of Eigen's own
// dst.noalias() (+)= M * v (alpha 1) or -M * v (alpha -1): Eigen's column-major matrix-vector
// kernel sums each row over the columns in order from zero and then sets dst_i = sum * alpha
// + dst_i (dst zeroed first when assigning), which is what the loop does. It skips the
// kernel's call and blocking set-up, most of its cost at plant sizes (bench: BM_FlagshipRun).
// Eigen takes other paths for a single row (an inner product) and for 128 columns or more
// (column blocks); those stay with Eigen.
[[gnu::noinline]] void eigen_product(Eigen::VectorXd& dst, const Eigen::MatrixXd& M,
                                     const Eigen::VectorXd& v, double alpha, bool add) {
  if (alpha == 1.0) {
    add ? (dst.noalias() += M * v) : (dst.noalias() = M * v);
  } else {
    add ? (dst.noalias() += -M * v) : (dst.noalias() = -M * v);
  }
}

inline void product(Eigen::VectorXd& dst, const Eigen::MatrixXd& M, const Eigen::VectorXd& v,
                    double alpha, bool add) {
  const Eigen::Index rows = M.rows(), cols = M.cols();
  if ((rows == 1 && cols != 1) || cols >= 128) {
    eigen_product(dst, M, v, alpha, add);
    return;
  }
  const double* m = M.data();
  const double* x = v.data();
  double* d = dst.data();
  for (Eigen::Index i = 0; i < rows; ++i) {
    double c = 0.0;
    for (Eigen::Index j = 0; j < cols; ++j) c += m[j * rows + i] * x[j];
    d[i] = c * alpha + (add ? d[i] : 0.0);
  }
}

class LinearProcess : public PlantProcess {
 public:
  LinearProcess(const LinearPlant& plant, const PlantRun& run)
      : plant_(plant),
        disturbance_(*run.disturbance),
        recentre_(run.recentre),
        rng_(kernel::make_stream(run.seed, run.run,
                                 kernel::stream_id(kernel::StreamKind::kPlant, 0))),
        w_sqrt_(psd_sqrt(plant.W)),
        w_(plant.nw()),
        scaled_(plant.nw()),
        next_(plant.n()) {}

  bool step(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) override {
    if (k == 0) return false;
    draw_standard_normal(rng_, w_);
    if (recentre_)
      product(s.recentre, plant_.A, s.x, -1.0, false);  // deadbeat: known to every estimator
    advance(k, u_applied, s);
    s.x.swap(next_);
    return true;
  }

 protected:
  // next_ = A x + Bu u + recentre + Bw w with w_ holding N(0, I) draws.
  virtual void advance(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) {
    product(scaled_, w_sqrt_, w_, 1.0, false);  // into its own buffer: no temporary, no allocation
    w_.swap(scaled_);
    disturbance_.at(k - 1, w_);  // deterministic part of w[k-1]
    product(s.drive, plant_.Bu, u_applied, 1.0, false);
    s.drive += s.recentre;
    product(next_, plant_.A, s.x, 1.0, false);
    next_ += s.drive;
    product(next_, plant_.Bw, w_, 1.0, true);
  }

  const LinearPlant& plant_;
  const Disturbance& disturbance_;
  bool recentre_;
  kernel::Rng rng_;
  Eigen::MatrixXd w_sqrt_;
  Eigen::VectorXd w_, scaled_, next_;
};

// x[k] = A_m x[k-1] + Bu_m u + Bw_m w with m = theta[k-1] drawn from the mode chain.
class JumpLinearProcess final : public LinearProcess {
 public:
  JumpLinearProcess(const LinearPlant& plant, const PlantRun& run)
      : LinearProcess(plant, run),
        mode_rng_(kernel::make_stream(run.seed, run.run,
                                      kernel::stream_id(kernel::StreamKind::kPlant, 1))) {
    for (const auto& pm : plant.modes) mode_w_sqrt_.push_back(psd_sqrt(pm.W));
  }

  bool drive_is_nominal() const override { return false; }

 private:
  void advance(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) override {
    const auto count = static_cast<Eigen::Index>(plant_.modes.size());
    boost::random::uniform_01<double> uniform;
    const double u = uniform(mode_rng_);
    double c = 0.0;
    int m = static_cast<int>(count) - 1;
    for (Eigen::Index i = 0; i < count; ++i) {
      c += k == 1 ? plant_.mode_initial(i) : plant_.mode_transition(s.mode, i);
      if (u < c) {
        m = static_cast<int>(i);
        break;
      }
    }
    s.mode = m;
    const PlantMode& pm = plant_.modes[static_cast<std::size_t>(m)];
    product(s.drive, pm.Bu, u_applied, 1.0, false);
    s.drive += s.recentre;
    product(next_, pm.A, s.x, 1.0, false);
    next_ += s.drive;
    product(scaled_, mode_w_sqrt_[static_cast<std::size_t>(m)], w_, 1.0, false);
    w_.swap(scaled_);
    disturbance_.at(k - 1, w_);  // deterministic part of w[k-1]
    product(next_, pm.Bw, w_, 1.0, true);
  }

  kernel::Rng mode_rng_;
  std::vector<Eigen::MatrixXd> mode_w_sqrt_;
};

// The true state is the vehicle's longitudinal motion (position, speed[, acceleration]).
class VehicleProcess final : public PlantProcess {
 public:
  explicit VehicleProcess(const PlantRun& run) : mobility_(*run.mobility), vehicle_(run.vehicle) {}
  bool step(std::int64_t, const Eigen::VectorXd&, PlantSignals& s) override {
    const VehicleState& v = mobility_.vehicle(vehicle_);
    const double m[3] = {v.pos, v.speed, v.accel};
    for (Eigen::Index i = 0; i < s.x.size() && i < 3; ++i) s.x(i) = m[i];
    return true;
  }

 private:
  MobilityRun& mobility_;
  int vehicle_;
};

}  // namespace

std::unique_ptr<PlantProcess> linear_process(const LinearPlant& plant, const PlantRun& run) {
  return std::make_unique<LinearProcess>(plant, run);
}
std::unique_ptr<PlantProcess> jump_linear_process(const LinearPlant& plant, const PlantRun& run) {
  return std::make_unique<JumpLinearProcess>(plant, run);
}
std::unique_ptr<PlantProcess> vehicle_process(const LinearPlant&, const PlantRun& run) {
  return std::make_unique<VehicleProcess>(run);
}

std::unique_ptr<PlantProcess> make_plant_process(const LinearPlant& plant, const PlantRun& run) {
  return plant.process ? plant.process(plant, run) : linear_process(plant, run);
}

}  // namespace ncosim::models
