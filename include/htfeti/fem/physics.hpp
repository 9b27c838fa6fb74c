// The physics of a problem and the assembly of one subdomain (DESIGN.md, fem/):
//  - laplace: -div(grad u) = source, one dof per node, kernel = the constants;
//  - elasticity: isotropic linear elasticity (E, nu; plane strain in 2D), dim dofs per node
//    (node-major: u_x, u_y[, u_z]), body force density * gravity, kernel = the rigid body
//    motions (3 in 2D, 6 in 3D) centred at the centroid of the nodes.
// Loads use the centroid rule: a source (or body force) evaluated at the cell's centroid times
// the cell's measure, shared equally by its nodes (exact for constant data on affine cells).
//
// assemble_subdomain() returns K_i, f_i (volume loads only; the caller adds tractions), the
// orthonormal kernel R_i computed per connected part of the subdomain (a METIS part that is not
// connected has one kernel block per part), and the dofs to fix for K^+: for each part, dim R
// dofs chosen by column-pivoted QR of the part's kernel rows at a few well-separated nodes
// (centre-nearest node first), so that R restricted to them is invertible and K K^+ K = K.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/fem/element.hpp"
#include "htfeti/linalg/orthonormal.hpp"
#include "htfeti/mesh/subdomain_mesh.hpp"

namespace htfeti {

enum class PhysicsKind { laplace, elasticity };
inline constexpr std::array<EnumName<PhysicsKind>, 2> kPhysicsNames{
    {{PhysicsKind::laplace, "laplace"}, {PhysicsKind::elasticity, "elasticity"}}};
PhysicsKind parse_physics(const std::string& name);  // throws std::invalid_argument
std::string to_string(PhysicsKind kind);

struct Physics {
  PhysicsKind kind = PhysicsKind::laplace;
  int dim = 2;
  Material material;   ///< elasticity
  double density = 0;  ///< elasticity: body force density * gravity
  std::array<double, 3> gravity{0, 0, 0};
  /// A positive coefficient field c(x, y, z) (an Expression; empty: 1) that multiplies each
  /// element's stiffness, evaluated at the element's centroid: the conductivity of a Laplace
  /// problem, a factor on Young's modulus in elasticity (coefficient jumps between materials).
  std::string coefficient;
  int dofs_per_node() const { return kind == PhysicsKind::laplace ? 1 : dim; }
  int kernel_dimension() const { return kind == PhysicsKind::laplace ? 1 : (dim == 2 ? 3 : 6); }
  /// Throws std::invalid_argument for non-physical values (E <= 0, nu outside (-1, 0.5), ...).
  void validate() const;
};

/// The kernel of the physics at n nodes with coordinates xyz (3 per node), centred at their
/// centroid, not normalized: n dofs_per_node x kernel_dimension (Laplace: ones).
Eigen::MatrixXd physics_kernel(const Physics& physics, const double* xyz, int n);

/// Source of a Laplace problem at a point (the centroid of a cell).
using SourceFunction = std::function<double(const std::array<double, 3>&)>;

struct AssembledSubdomain {
  Eigen::SparseMatrix<double> K;
  Eigen::VectorXd f;
  Eigen::MatrixXd R;            ///< orthonormal kernel basis
  std::vector<int> fixed_dofs;  ///< R.cols() dofs fixed for K^+
  int parts = 1;                ///< connected parts of the subdomain
  /// The coefficient field's smallest and largest value on the cells (1 without a field).
  double coefficient_min = 1, coefficient_max = 1;
};

/// Stiffness only (for rebuilding K after it was freed): the element matrices' nonzero entries
/// (stiffness_triplets) summed, for each matrix entry, in element order, so the same matrix bit
/// for bit as Eigen's setFromTriplets of them (tested); assembled column by column in work arrays
/// kept per thread, so that only the matrix itself is allocated.
Eigen::SparseMatrix<double> assemble_stiffness(const SubdomainMesh& mesh, const Physics& physics);

class Expression;
/// The coefficient field at the centroid of the cell whose nodes are `cell` (coords: 3 per
/// node), as the assembly takes it; throws std::invalid_argument naming the point where it is
/// not positive.
double cell_coefficient(const Expression& field, CellType type, const std::vector<double>& coords,
                        const int* cell);
/// The nonzero entries of every element's stiffness matrix (times the coefficient at its
/// centroid) as (row, column, value), cell by cell in cell order.
std::vector<Eigen::Triplet<double>> stiffness_triplets(const SubdomainMesh& mesh,
                                                       const Physics& physics);
/// u'K u element by element, without assembling K (the same element matrices and coefficient
/// as assemble_stiffness; equal to u'(K u) up to the order of the sums). For the energy of the
/// report once K has been freed; on generated boxes a few element matrices serve all cells.
double stiffness_form(const SubdomainMesh& mesh, const Physics& physics, const Eigen::VectorXd& u);
/// K, the volume load (source for Laplace, density * gravity for elasticity), kernel, fixed dofs.
AssembledSubdomain assemble_subdomain(const SubdomainMesh& mesh, const Physics& physics,
                                      const SourceFunction& source);
/// Adds to share_of_node (one entry per node) each facet's measure of a facet group shared
/// equally by its nodes (the nodal areas of a uniform traction of 1).
void add_facet_shares(const SubdomainMesh& mesh, const SubdomainMesh::FacetGroup& group,
                      std::vector<double>& share_of_node);
/// Adds a uniform traction (elasticity: a vector; Laplace: a flux, component 0) on the facets
/// of a facet group: each facet's measure times the traction, shared equally by its nodes.
void add_traction(const SubdomainMesh& mesh, const SubdomainMesh::FacetGroup& group,
                  const Physics& physics, const std::array<double, 3>& traction,
                  Eigen::VectorXd& f);

}  // namespace htfeti
