// Estimates of ||A|| for a symmetric positive semidefinite A (SMALBE-M's rho, M_0 and MPRGP's
// step length are multiples of it). Both return a Rayleigh-Ritz value, which never exceeds
// ||A||; callers keep a safety factor.
//  - power method: the Rayleigh quotient of A^k x; one application of A per iteration;
//  - Lanczos: the largest eigenvalue of the k x k tridiagonal matrix of the Lanczos process,
//    i.e. the best Ritz value from the whole Krylov space span{x, Ax, ..., A^(k-1) x}, which
//    contains the power iterate: never below the power method's value after as many products,
//    and it converges much faster. One application of A, two reductions and an eigenvalue
//    problem of size k (k <= 50, negligible) per iteration; no reorthogonalization (only the
//    extreme Ritz value is wanted, and loss of orthogonality does not spoil it).
#pragma once

#include <string>

#include "htfeti/enum_names.hpp"
#include "htfeti/qp/operator.hpp"

namespace htfeti::qp {

enum class NormEstimate { lanczos, power };
inline constexpr std::array<EnumName<NormEstimate>, 2> kNormEstimateNames{
    {{NormEstimate::lanczos, "lanczos"}, {NormEstimate::power, "power"}}};
NormEstimate parse_norm_estimate(const std::string& name);  // throws std::invalid_argument
std::string to_string(NormEstimate method);

/// start: a nonzero starting vector (its choice should not depend on the number of ranks).
/// Stops after max_iterations or when two successive estimates differ by less than rtol.
double estimate_norm(Operator& A, const Vec& start, const Reducer& red, int max_iterations = 50,
                     double rtol = 1e-3);

/// The same by the Lanczos process (same arguments and stopping rule).
double estimate_norm_lanczos(Operator& A, const Vec& start, const Reducer& red,
                             int max_iterations = 50, double rtol = 1e-3);

}  // namespace htfeti::qp
