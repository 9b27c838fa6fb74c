// ParaView output of a solution: one VTU file (one rank) or a PVTU file with one VTU piece per
// rank. Binary by default (VTK XML "appended" raw data with 64-bit headers; ASCII on request).
// Fields: the displacement/potential "u" on the points (a 3-vector for elasticity), the contact
// force carried by each copy ("contact_force", B_I^T lambda: summed over a node's copies it is the
// nodal contact force), and per cell the subdomain, cluster and rank ids and, for elasticity, the
// von Mises stress at the cell centroid. Every subdomain writes its own copy of its nodes.
//
// Files are written under temporary names next to the target and renamed only when every rank
// has written its piece without error; on failure nothing is left behind (the error is agreed on
// by all ranks and thrown).
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/model.hpp"

namespace htfeti {

struct VtuOptions {
  bool ascii = false;
};

/// The file names that write_vtu would write (the .vtu, or the .pvtu and its pieces).
std::vector<std::string> vtu_files(const std::string& path, int ranks);

/// Writes the solution; returns the path of the main file (.vtu or .pvtu). Collective.
std::string write_vtu(const std::string& path, const Model& model, DualProblem& dual,
                      const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda,
                      const VtuOptions& options = {});

}  // namespace htfeti
