#include "sod_design.h"
#include "estimators/design/sod_bounds.h"
#include <gtest/gtest.h>
#include <iostream>
using namespace ncosim::est::sod;
SodSystem ex51() {
  SodSystem s;
  s.A.resize(3,3); s.A << 1.005, 0.221, 0.171, -0.031, 1.008, 0.136, 0.049, 0.038, 1.028;
  s.Bw.resize(3,2); s.Bw << -0.229, 0.023, 0.231, 0.211, -0.186, 0.245;
  s.C.resize(2,3); s.C << 0.519, -0.233, 0.095, 0.569, 0, 0;
  s.Cz = Eigen::MatrixXd::Identity(3,3);
  s.sensor_rows = {0,1,2};
  s.w_rms = 0.468; s.v_rms = Eigen::Vector2d(0.032, 0.032);
  return s;
}
TEST(S, Z0) {
  auto r = design_all_measurements(ex51());
  std::cout << r.status << " z0=" << r.bound << " t=" << r.seconds << "\n";
  SodDesignSpec d; d.sigma2_delta = Eigen::Vector2d(0.236*0.236/3, 0.098*0.098/3);
  auto a = design_sod(ex51(), d);
  std::cout << a.status << " det=" << a.bound << " t=" << a.seconds << " lmis " << a.lmis << "\n";
  d.approach = Approach::kStochastic; Eigen::Vector2d r2(0.9, 0.75);
  d.beta_lower = Eigen::Vector2d(uniform_beta(0.236,0.9), uniform_beta(0.098,0.75));
  d.sigma2_delta = Eigen::Vector2d(uniform_sigma2(0.236,0.9), uniform_sigma2(0.098,0.75));
  auto b = design_sod(ex51(), d);
  std::cout << b.status << " sto=" << b.bound << " t=" << b.seconds << " lmis " << b.lmis << "\n";
  d.vertices = Vertices::kLower;
  auto c = design_sod(ex51(), d);
  std::cout << c.status << " sto lower=" << c.bound << " t=" << c.seconds << "\n";
}
#include <random>
TEST(S, Vertex) {
  SodDesignSpec d; d.approach = Approach::kStochastic;
  d.beta_lower = Eigen::Vector2d(uniform_beta(0.3,0.9), uniform_beta(0.2,0.75));
  d.sigma2_delta = Eigen::Vector2d(uniform_sigma2(0.3,0.9), uniform_sigma2(0.2,0.75));
  auto b = design_sod(ex51(), d);
  std::mt19937_64 g(1); std::uniform_real_distribution<double> u(0,1);
  double worst = 1e9;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector2d be;
    for (int s = 0; s < 2; ++s) be(s) = d.beta_lower(s) + u(g) * (1 - d.beta_lower(s));
    Eigen::MatrixXd Psi = psi_at(ex51(), b, be);
    worst = std::min(worst, Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Psi).eigenvalues().minCoeff());
  }
  std::cout << "worst interior min eig " << worst << "\n";
  d.vertices = Vertices::kLower;
  auto c = design_sod(ex51(), d);
  worst = 1e9;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector2d be;
    for (int s = 0; s < 2; ++s) be(s) = d.beta_lower(s) + u(g) * (1 - d.beta_lower(s));
    worst = std::min(worst, Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(psi_at(ex51(), c, be)).eigenvalues().minCoeff());
  }
  std::cout << "lower-only worst interior min eig " << worst << "\n";
}
