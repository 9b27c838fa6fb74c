// What the FETI stage is given for each subdomain of a rank (DESIGN.md: "feti sees
// SubdomainSystems and DofSharing, never a mesh"), and the global facts it needs.
//
// - SubdomainSystem: K_i (rebuildable after it is freed), f_i, the orthonormal kernel R_i and
//   the dofs fixed for K^+;
// - DofSharing: per local node its global id, coordinates (for the kernel restricted to an
//   interface object), the subdomains holding a copy (canonical order) and whether it lies on
//   the domain boundary; dofs are node-major (node * dofs_per_node + component);
// - the conditions: Dirichlet dofs with values, and contact rows n.(u_a - u_b) <= gap (b absent
//   for a rigid obstacle).
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"

namespace htfeti {

/// Which primal constraints join the subdomains of a cluster (paper, Section 5): corners
/// (vertices), averages of the kernel over shared edges (2D) or faces (3D), or both.
enum class Glue { corners, averages, corners_averages };
inline constexpr std::array<EnumName<Glue>, 3> kGlueNames{
    {{Glue::corners, "corners"},
     {Glue::averages, "averages"},
     {Glue::corners_averages, "corners+averages"}}};
Glue parse_glue(const std::string& name);  // throws std::invalid_argument
std::string to_string(Glue glue);

struct SubdomainSystem {
  int id = 0;  ///< global subdomain id
  int dofs_per_node = 1;
  Eigen::SparseMatrix<double> K;
  /// Rebuilds K after it was freed (the factors are computed again for the reconstruction).
  std::function<Eigen::SparseMatrix<double>()> assemble;
  /// u'K u without K (element by element), for the energy once K was freed; optional.
  std::function<double(const Eigen::VectorXd&)> quadratic_form;
  Eigen::VectorXd f;
  Eigen::MatrixXd R;            ///< orthonormal kernel basis, one column per rigid mode
  std::vector<int> fixed_dofs;  ///< R.cols() dofs set to zero by K^+ (sorted)
  /// A subdomain of a generated grid, whose matrix is expected to equal others' (their factors
  /// are shared through the numeric cache): its factor keeps its double values beside a
  /// single-precision copy (Subdomain::SingleCopy). A property of the subdomain alone, so that
  /// which solves are refined does not depend on how subdomains are spread over the ranks.
  bool repeats = false;
  /// The coefficient field's smallest and largest value on the subdomain's cells (1 without a
  /// field): their ratio above kWeightedProjectorSpread, a jump runs through it (solver.hpp).
  double coefficient_min = 1, coefficient_max = 1;
};

struct DofSharing {
  std::vector<long long> global_node;
  std::vector<double> coords;  ///< 3 per node
  std::vector<int> copy_offset, copy_list;
  std::vector<char> on_boundary;
  /// The frame the kernel of an averaged object (face, edge) is computed in, set by the model:
  /// maps the object's node coordinates (3 per node, n nodes, in place; the first node is the
  /// object's first by global id). Empty: the coordinates as they are. A generated box sets
  /// offsets from the first node in whole grid spacings (fem/grid_offsets.hpp), so that equal
  /// objects of a box get the same primal constraints bit for bit.
  std::function<void(double* xyz, int n)> kernel_frame;
  int num_nodes() const { return static_cast<int>(global_node.size()); }
  int num_copies(int k) const { return copy_offset[k + 1] - copy_offset[k]; }
  const int* copies(int k) const { return copy_list.data() + copy_offset[k]; }
};

struct DirichletDof {
  int node;       ///< local node
  int component;  ///< 0 .. dofs_per_node - 1
  double value;
};

/// One node's part of an inequality row of B (contact), given to every subdomain holding a
/// copy of the node. A row is
///     n . (sum_j c_j avg u_j) <= W gap,
/// over the nodes j of the row with coefficients c_j (avg: the average of the node's copies):
///  - a node-to-node row n.(u_a - u_b) <= gap: c_a = +1, c_b = -1 (b absent for a rigid obstacle),
///    W = 1;
///  - a mortar row of a slave node i (model/mortar.hpp): c_j = D_ij on the slave nodes, -M_ik
///    on the master nodes, W = sum_j D_ij (the integral of the slave node's basis function over
///    the part of its support facing the master) and gap = the weighted gap / W (a length).
/// The row is scaled to unit norm in B~ (constraints.hpp); `norm_sq` is sum_j c_j^2 / copies_j
/// over all nodes of the row, which the model knows and a subdomain alone does not.
struct ContactRow {
  int node = 0;             ///< local node
  int side = 1;             ///< +1: node a or a slave node; -1: node b or a master node
  bool key = true;          ///< the node the row is keyed by (a, or the slave node of a mortar row)
  long long node_a = 0;     ///< global id of a or of the slave node (the key that orders the row)
  double coefficient = 1;   ///< c_j of this node
  int copies = 1;           ///< copies of this node (subdomains holding it)
  double norm_sq = 1;       ///< sum over the row's nodes of c_j^2 / copies_j
  double weight = 1;        ///< W: 1 for a node-to-node row, sum_j D_ij for a mortar row
  int owner_subdomain = 0;  ///< lowest subdomain holding a copy of a row node
  std::array<double, 3> direction{1, 0, 0};  ///< unit normal n (dofs_per_node components used)
  double gap = 0;                            ///< in length units (the right-hand side is W gap)
  std::array<double, 3> point{0, 0, 0};      ///< coordinates of a / the slave node (the report)
  /// The contact condition the row comes from: a node may carry one row per condition (a
  /// corner under a floor and beside a wall), each its own multiplier.
  int condition = 0;
  /// The contact area the row stands for: a node-to-node row, the node's share of the
  /// condition's facets on this subdomain (each facet's measure shared equally by its nodes;
  /// summed over the copies, the node's area; 0 where the group has no facets); a mortar row,
  /// W on the slave node's entry (0 on the others).
  double area = 0;
  /// Friction on the row: Tresca's slip bound per unit area (>= 0), or Coulomb's coefficient
  /// mu (>= 0; the bound is then mu times the normal pressure of the previous solve); < 0: none.
  /// The tangential rows t.(sum_j c_j avg u_j) take the normal row's coefficients: in 2D
  /// t = (-n_y, n_x), in 3D t1 = `tangent` (unit, orthogonal to n) and t2 = n x t1.
  /// 3D: the node's Dirichlet conditions leave it one tangential direction (`tangent_rows` =
  /// 1: the row along `tangent` alone, its set an interval; FrictionRows in contact_pairs.hpp).
  double slip_bound = -1;
  double friction_coefficient = -1;
  std::array<double, 3> tangent{0, 0, 0};
  int tangent_rows = 2;
};

/// One local subdomain's input: moved into the FETI stage, which keeps what it needs.
struct SubdomainInput {
  SubdomainSystem system;
  DofSharing sharing;
  std::vector<DirichletDof> dirichlet;
  std::vector<ContactRow> contact;
};

/// Global structure: clusters own contiguous subdomain ranges (cluster-major numbering).
struct FetiLayout {
  int dim = 2;
  int dofs_per_node = 1;
  long long num_nodes = 0;  ///< global nodes (keys of the per-node rows)
  int num_subdomains = 0;
  int num_clusters = 0;
  std::vector<int> cluster_first;  ///< num_clusters + 1 offsets into the subdomain ids
  Glue glue = Glue::averages;
  /// The kernel of the physics at n nodes (3 coordinates each), unnormalized columns.
  std::function<Eigen::MatrixXd(const double* xyz, int n)> kernel;
  int cluster_of(int s) const;
  int cluster_size(int c) const { return cluster_first[c + 1] - cluster_first[c]; }
  /// Clusters [first, last) owned by rank r of P (contiguous blocks).
  std::pair<int, int> cluster_range(int r, int P) const;
  int rank_of_cluster(int c, int P) const;
  int rank_of_subdomain(int s, int P) const { return rank_of_cluster(cluster_of(s), P); }
};

}  // namespace htfeti
