// Estimate of ||A|| for a symmetric positive semidefinite A by the power method. The Rayleigh
// quotient it returns never exceeds ||A||; callers keep a safety factor.
// Cost: one application of A per iteration.
#pragma once

#include "htfeti/qp/operator.hpp"

namespace htfeti::qp {

/// start: a nonzero starting vector (its choice should not depend on the number of ranks).
/// Stops after max_iterations or when two successive estimates differ by less than rtol.
double estimate_norm(Operator& A, const Vec& start, const Reducer& red, int max_iterations = 50,
                     double rtol = 1e-3);

}  // namespace htfeti::qp
