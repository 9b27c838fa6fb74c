// Linear finite elements: quad4 and tri3 in 2D, hex8 and tet4 in 3D, with the two physics of
// htfeti: the Laplacian (one dof per node) and isotropic linear elasticity (dim dofs per node;
// plane strain in 2D). Element matrices are integrated by Gauss quadrature (2 x 2 or 2 x 2 x 2
// for quad4/hex8, one point for the simplices, which is exact for their constant gradients).
//
// Node orders are Gmsh's (and VTK's): quad4 counter-clockwise, hex8 bottom face
// counter-clockwise then the top face, tet4 any positively or negatively oriented order (the
// absolute Jacobian is used).
#pragma once

#include <Eigen/Dense>
#include <array>
#include <string>

#include "htfeti/mesh/cell.hpp"

namespace htfeti {

/// Material of the elasticity physics: Young's modulus and Poisson's ratio.
struct Material {
  double young = 1.0;
  double poisson = 0.3;
};

/// Whether the cell is valid: the Jacobian determinant at the corners of the reference cell
/// (constant for simplices) has one sign and is above 1e-12 h^dim in magnitude (h the cell's
/// largest coordinate extent); false for an inverted, self-intersecting (bow-tie) or degenerate
/// cell, or non-finite coordinates.
bool cell_is_valid(CellType type, const double* x);

/// Element stiffness for -div(grad u) (Laplace) on a cell with coordinates x (3 per node,
/// unused components zero). Rows/columns follow the cell's nodes.
Eigen::MatrixXd laplace_stiffness(CellType type, const double* x);
/// Element stiffness of linear elasticity; dofs ordered node-major (u_x, u_y[, u_z]) per node.
Eigen::MatrixXd elasticity_stiffness(CellType type, const double* x, const Material& material);
/// The integral of each shape function over the cell (the consistent load of a unit source).
Eigen::VectorXd shape_integrals(CellType type, const double* x);
/// Measure (area or volume) of the cell and its centroid.
double cell_measure(CellType type, const double* x);
std::array<double, 3> cell_centroid(CellType type, const double* x);
/// Strain-displacement at the cell centroid: 6 x (3 n) in 3D, 3 x (2 n) in 2D (engineering
/// shear), for the von Mises stress of a displacement.
Eigen::MatrixXd strain_matrix_at_centroid(CellType type, const double* x);
/// Elasticity matrix D (6 x 6 in 3D, 3 x 3 plane strain in 2D).
Eigen::MatrixXd elasticity_matrix(int dim, const Material& material);
/// von Mises stress of a stress vector (Voigt order xx, yy, zz, xy, yz, zx in 3D; xx, yy, xy in
/// 2D plane strain, with s_zz = nu (s_xx + s_yy)).
double von_mises(int dim, const Eigen::VectorXd& stress, double poisson);

/// Measure (length or area) of a facet with coordinates x (3 per node), 2, 3 or 4 nodes.
double facet_measure(int dim, int nodes, const double* x);

}  // namespace htfeti
