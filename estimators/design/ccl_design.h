// estimators/design/ccl_design.h — the paper's design method for the jump observer gains
// (Dolz et al. 2014, section 4): problem (27) (min tr(P) s.t. E{P} <= P written as the LMI
// (25) with Q = P^-1, R = S_P^-1) by the cone-complementarity linearisation (CCL) of El Ghaoui
// et al. inside a bisection on gamma >= tr(P), on the LMI layer (lmi/lmi.h).
//
// The LMI is (25) split by N: P - sum_N Y_N >= 0 and, for each N, one block
//   [[Y_N, sqrt(w) F A^N, sqrt(w) F S_W^1/2, sqrt(w) L eta V^1/2, ...], [.., Q (R for the tail), I, I, ...]]
// (Schur complement of Y_N >= sum over the patterns of N of w (F X_N F' + L eta V eta L')), with S_P
// the variable and P = S_P - p0 Abar S_P Abar' (eq. 19) an expression. S1–S3 share one gain
// variable per group (the paper's equalities L_{N,i} = L_{N,j}); a gain has only the columns of
// the fictitious sensors its patterns deliver. A bisection step gamma is accepted when the gains
// of a CCL iterate have an exact fixed point (evaluate_jump_gains) with tr(P) <= gamma; the
// relaxation (Q, R free) gives the initial lower bound. The result is reported through
// evaluate_jump_gains, like the iterative design.
#pragma once

#include <string>
#include <vector>

#include "estimators/design/jump_design.h"
#include "lmi/lmi.h"

namespace ncosim::est {

struct CclOptions {
  int max_ccl_iterations = 20;       // k_max of the paper's step 4
  double relative_gap = 1e-3;        // bisection stops when gamma_u - gamma_l < gap gamma_u
  int max_bisections = 40;
  int sdp_max_iterations = 100;      // CSDP's iteration limit per SDP
  bool verbose = false;              // CSDP log and the bisection trace on stderr
};

struct CclInfo {
  lmi::SdpSize size;        // of the CCL step SDP
  int sdp_solves = 0;
  int bisections = 0;
  int ccl_iterations = 0;   // total over the bisection
  double lower_bound = 0.0; // final gamma_l: CCL failed there (not a certified bound; the relaxation is)
  double upper_bound = 0.0; // final gamma_u (tr P of the returned gains)
  std::string lmi_status = "optimal";  // status of the first SDP that failed, if the design failed
};

// On failure the returned design has stable = false and status = the LMI status
// ("infeasible", "numerical_trouble", ...) or "no_feasible_gains".
JumpDesign design_jump_ccl(const ExtendedModel& ext, const std::vector<double>& pattern_prob, int Nbar,
                           Grouping grouping, const CclOptions& options = {}, CclInfo* info = nullptr);

}  // namespace ncosim::est
