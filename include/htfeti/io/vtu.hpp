// VTK XML unstructured-grid output for ParaView: the primal solution u on every subdomain's own
// nodes (point data), with subdomain, cluster and rank ids as cell data. With one rank, FILE.vtu;
// with P ranks, one piece per rank (FILE_<r>.vtu) and FILE.pvtu naming them. Files are written
// to a temporary name and renamed, so a failed run leaves no half-written file.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "htfeti/feti/dual_problem.hpp"

namespace htfeti {

/// Collective. Returns the path users open (the .vtu or the .pvtu).
std::string write_vtu(const std::string& path, const DualProblem& dual,
                      const std::vector<Eigen::VectorXd>& u);

}  // namespace htfeti
