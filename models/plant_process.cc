// models/plant_process.cc — the built-in plant processes.
#include "models/plant_process.h"

#include <boost/random/uniform_01.hpp>

#include "models/noise.h"

namespace ncosim::models {

namespace {

class LinearProcess : public PlantProcess {
 public:
  LinearProcess(const LinearPlant& plant, const PlantRun& run)
      : plant_(plant),
        disturbance_(*run.disturbance),
        recentre_(run.recentre),
        rng_(sim::make_stream(run.seed, run.run, sim::stream_id(sim::StreamKind::kPlant, 0))),
        w_sqrt_(psd_sqrt(plant.W)),
        w_(plant.nw()),
        scaled_(plant.nw()),
        next_(plant.n()) {}

  bool step(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) override {
    if (k == 0) return false;
    draw_standard_normal(rng_, w_);
    if (recentre_) s.recentre.noalias() = -plant_.A * s.x;  // deadbeat: known to every estimator
    advance(k, u_applied, s);
    s.x.swap(next_);
    return true;
  }

 protected:
  // next_ = A x + Bu u + recentre + Bw w with w_ holding N(0, I) draws.
  virtual void advance(std::int64_t k, const Eigen::VectorXd& u_applied, PlantSignals& s) {
    scaled_.noalias() = w_sqrt_ * w_;  // into its own buffer: no temporary, no allocation
    w_.swap(scaled_);
    disturbance_.at(k - 1, w_);  // deterministic part of w[k-1]
    s.drive.noalias() = plant_.Bu * u_applied;
    s.drive += s.recentre;
    next_.noalias() = plant_.A * s.x;
    next_ += s.drive;
    next_.noalias() += plant_.Bw * w_;
  }

  const LinearPlant& plant_;
  const Disturbance& disturbance_;
  bool recentre_;
  sim::Rng rng_;
  Eigen::MatrixXd w_sqrt_;
  Eigen::VectorXd w_, scaled_, next_;
};

// x[k] = A_m x[k-1] + Bu_m u + Bw_m w with m = theta[k-1] drawn from the mode chain.
class JumpLinearProcess final : public LinearProcess {
 public:
  JumpLinearProcess(const LinearPlant& plant, const PlantRun& run)
      : LinearProcess(plant, run), mode_rng_(sim::make_stream(run.seed, run.run, sim::stream_id(sim::StreamKind::kPlant, 1))) {
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
    s.drive.noalias() = pm.Bu * u_applied;
    s.drive += s.recentre;
    next_.noalias() = pm.A * s.x;
    next_ += s.drive;
    scaled_.noalias() = mode_w_sqrt_[static_cast<std::size_t>(m)] * w_;
    w_.swap(scaled_);
    disturbance_.at(k - 1, w_);  // deterministic part of w[k-1]
    next_.noalias() += pm.Bw * w_;
  }

  sim::Rng mode_rng_;
  std::vector<Eigen::MatrixXd> mode_w_sqrt_;
};

// The true state is the vehicle's longitudinal motion (position, speed[, acceleration]).
class VehicleProcess final : public PlantProcess {
 public:
  explicit VehicleProcess(const PlantRun& run) : mobility_(*run.mobility), vehicle_(run.vehicle) {}
  bool step(std::int64_t, const Eigen::VectorXd&, PlantSignals& s) override {
    const sim::VehicleState& v = mobility_.vehicle(vehicle_);
    const double m[3] = {v.pos, v.speed, v.accel};
    for (Eigen::Index i = 0; i < s.x.size() && i < 3; ++i) s.x(i) = m[i];
    return true;
  }

 private:
  sim::MobilityRun& mobility_;
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
