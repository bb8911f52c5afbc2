// mass_spring_damper.cc — a new plant kind from physical parameters: m x'' + c x' + k x = u + w,
// state [position; velocity], a force input u and a white force disturbance w of intensity
// sigma^2 (N^2 s), discretised exactly at the control period by ncosim's models::discretise.
// Keys: mass (kg, > 0), stiffness (N/m, >= 0), damping (N s/m, >= 0), sigma (N sqrt(s), > 0),
// x0 (default 0).
#include <fmt/format.h>

#include "kinds.h"

namespace {

ncosim::models::LinearPlant read_mass_spring_damper(const ncosim::config::Table& t, double period) {
  const double m = t.number("mass"), k = t.number_or("stiffness", 0.0),
               c = t.number_or("damping", 0.0);
  const double sigma = t.number("sigma");
  if (!(m > 0.0)) t.fail("mass", fmt::format("expected a mass > 0, got {}", m));
  if (!(k >= 0.0)) t.fail("stiffness", fmt::format("expected a stiffness >= 0, got {}", k));
  if (!(c >= 0.0)) t.fail("damping", fmt::format("expected a damping >= 0, got {}", c));
  if (!(sigma > 0.0)) t.fail("sigma", fmt::format("expected a noise intensity > 0, got {}", sigma));
  Eigen::Matrix2d Ac;
  Ac << 0.0, 1.0, -k / m, -c / m;
  const Eigen::Vector2d Bc(0.0, 1.0 / m);
  const Eigen::MatrixXd Wc = Eigen::MatrixXd::Constant(1, 1, sigma * sigma);
  ncosim::models::LinearPlant p = ncosim::models::discretise(Ac, Bc, Bc, Wc, period);
  p.x0 = t.has("x0") ? t.vector("x0") : Eigen::VectorXd::Zero(2);
  if (p.x0.size() != 2) t.fail("x0", fmt::format("expected 2 entries, got {}", p.x0.size()));
  return p;
}

}  // namespace

void register_mass_spring_damper(ncosim::models::PlantRegistry& registry) {
  registry.add("mass_spring_damper",
               "m x'' + c x' + k x = u + w, exact discretisation (example extension): mass, "
               "stiffness, damping, "
               "sigma, x0",
               read_mass_spring_damper);
}
