// estimators/design/ccl_design.h — the paper's design method for the jump observer gains
// (Dolz et al. 2014, section 4): problem (27) (min tr(P) s.t. E{P} <= P written as the LMI
// (25) with Q = P^-1, R = S_P^-1) by the cone-complementarity linearisation (CCL) of El Ghaoui
// et al. inside a bisection on gamma >= tr(P), on the LMI layer (lmi/lmi.h).
//
// The LMI is (25) split by N: P - sum_c Y_c >= 0 and, per chunk c of the terms of one N, one block
//   [[Y_c, coef F A^N, coef F S_W^1/2, coef L eta V^1/2, ...], [.., Q (R for the tail), I, I, ...]]
// (Schur complement of Y_c >= sum over its terms of w (F X_N F' + L eta V eta L')), with S_P
// the variable and P = S_P - p0 Abar S_P Abar' (eq. 19) an expression. S1–S3 share one gain
// variable per group (the paper's equalities L_{N,i} = L_{N,j}); a gain has only the columns of
// the fictitious sensors its patterns deliver, and a group's patterns enter through the mean and
// covariance of their availability vector when that is smaller than one term per pattern
// (exact; see Piece in the source). A bisection step gamma is accepted when the gains of a CCL
// iterate have an exact fixed point (evaluate_jump_gains) with tr(P) <= gamma. The bisection's
// lower end is tr(P) of the exact S4 design (value iteration; a certified bound for every
// grouping), and the first CCL iterate is linearised at that design (s4_bound; without it the
// LMI relaxation with Q, R free gives the first gains and the lower end). Each step linearises
// at the best exact fixed point so far (CclStart) and ends, as a failure at gamma, when an
// iterate no longer improves it (patience) or after k_max iterations. The result is reported
// through evaluate_jump_gains, like the iterative design.
#pragma once

#include <string>
#include <vector>

#include "estimators/design/jump_design.h"
#include "lmi/lmi.h"

namespace ncosim::est {

// Step 2 of section 4 ("find a feasible solution") at each bisection step: kFeasible solves a
// feasibility SDP (the paper's text); kBestExact linearises at the best exact fixed point found
// so far (P, S_P of those gains, Q = P^-1, R = S_P^-1), which satisfies (25) at gamma_u.
enum class CclStart { kFeasible, kBestExact };

struct CclOptions {
  CclStart start = CclStart::kBestExact;
  int max_ccl_iterations = 20;  // k_max of the paper's step 4
  // A bisection step ends early (as a failure at this gamma) after `patience` consecutive CCL
  // iterations that lowered the best exact tr(P) by less than stall_tolerance (relative).
  int patience = 1;
  double stall_tolerance = 1e-3;
  double relative_gap = 1e-3;  // bisection stops when gamma_u - gamma_l < gap gamma_u
  // ... or, when the lower end is the exact S4 design's (s4_bound), after this many consecutive
  // steps that did not improve the best design by stall_tolerance (0: never; the paper's step 5
  // has only the gap). From the relaxation's loose lower end, failed steps are expected (gamma
  // below anything reachable) and only the gap ends the bisection.
  int max_fruitless_steps = 2;
  int max_bisections = 40;
  int sdp_max_iterations = 100;  // CSDP's iteration limit per SDP
  // CSDP's tolerances (axtol, atytol, objtol) for every SDP of the design. The SDPs only steer
  // the search: every candidate gain set is evaluated exactly (evaluate_jump_gains).
  double sdp_tolerance = 1e-5;
  // Write a group of patterns sharing a gain through the moments of its availability vector
  // when that is smaller (exact); false: one LMI term per pattern, as printed in the paper.
  bool group_moments = true;
  // Solve the SDPs on the model with its noise scaled so that the variables are of order one.
  bool normalise = true;
  // Start the bisection's lower end at tr(P) of the exact S4 design (a certified bound for
  // every grouping; the paper starts at 0) and linearise the first CCL iterate at it. false:
  // the LMI relaxation's min tr(P) (Q, R free), solved as the first SDP, gives both.
  bool s4_bound = true;
  bool verbose = false;  // CSDP log and the bisection trace on stderr
};

struct CclInfo {
  lmi::SdpSize size;  // of a bisection step's SDP
  int sdp_solves = 0;
  int bisections = 0;
  int ccl_iterations = 0;          // total over the bisection
  bool stopped_fruitless = false;  // the bisection ended on max_fruitless_steps, not on the gap
  // Why the bisection ended: "gap", "no_improvement" (max_fruitless_steps), "max_bisections";
  // empty when the design failed before it.
  std::string stop;
  double relaxation_bound =
      0.0;                // min tr(P) with Q, R free: a certified lower bound (0 when not solved)
  double s4_bound = 0.0;  // tr(P) of the exact S4 design (0 when not used)
  double lower_bound =
      0.0;  // final gamma_l: CCL failed there (not a certified bound; the relaxation is)
  double upper_bound = 0.0;            // final gamma_u (tr P of the returned gains)
  std::string lmi_status = "optimal";  // status of the first SDP that failed, if the design failed
};

// On failure the returned design has stable = false and status = the LMI status
// ("infeasible", "numerical_trouble", ...) or "no_feasible_gains".
JumpDesign design_jump_ccl(const ExtendedModel& ext, const std::vector<double>& pattern_prob,
                           int Nbar, Grouping grouping, const CclOptions& options = {},
                           CclInfo* info = nullptr);

}  // namespace ncosim::est
