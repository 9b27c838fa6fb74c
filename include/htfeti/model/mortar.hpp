// Mortar rows for contact between two bodies (docs/method.md, "Contact between bodies"):
// segment-to-segment in 2D, face-to-face by polygon clipping in 3D, small deformation, in the
// reference configuration.
//
// The weak non-penetration condition on the slave surface Gamma_s: for every slave node i
//     n_i . ( sum_j D_ij u_j - sum_k M_ik u_k ) <= g_i,
//     D_ij = int theta_i phi_j,   M_ik = int theta_i (psi_k o pi),
//     g_i = int theta_i n_i.(x_m o pi - x),
// the integrals over the part of Gamma_s that faces the master surface (pi: the projection of a
// slave point onto the master surface along the slave face's normal; phi_j: slave and psi_k:
// master basis functions; n_i: the slave node's normal, the facet normals around it averaged
// with their measures as weights). The test functions theta_i span the multiplier space:
// - dual (the default; Wohlmuth 2000, the discretization of Hueber and Wohlmuth's and Popp et
//   al.'s frictional mortar contact): on each slave facet theta_a = sum_b A_ab phi_b with
//   int theta_a phi_b = delta_ab int phi_b, so D is diagonal (for facets the master covers
//   whole), the weighted gap of a linear field is its nodal value, and the nodal conditions
//   lambda_i >= 0, |lambda_t,i| <= mu lambda_n,i are the weak ones. A facet that the master
//   covers only in part (the master surface's edge) keeps the standard functions, whose weights
//   stay positive (covered whole: the overlaps' measures sum to the facet's and every node's dual
//   weight equals its standard one; docs/method.md).
// - standard: theta_i = phi_i. D is the slave surface's mass matrix, and the multipliers, D^-T
//   applied to the nodal forces, oscillate node to node on unstructured meshes: on the 3D
//   Cattaneo-Mindlin sphere (tet4, h = 0.01) the stick zone's tangential tractions spread over
//   a factor 50 and its radius came out 9% small, against 4% with the dual space
//   (docs/results.md).
// D and M are integrated over the same intersections (segments in 2D, clipped polygons in 3D) by
// Gauss rules exact for the products of linear (tri3 facets) and bilinear (quad4 facets on
// parallelograms) shape functions, so sum_j D_ij = sum_k M_ik: a rigid translation leaves every
// row unchanged and a linear field continuous across a flat interface satisfies it with equality
// (the contact patch test), with either space.
//
// Contact search (once, in the reference configuration): the master facets are put in bins of a
// uniform grid (cell = the largest master facet's bounding box, at least the search distance);
// a slave facet looks only at the bins its bounding box, grown by the search distance, touches:
// O(n) work for n facets of bounded size ratio (O(n log n) with the sort of the bins). A pair
// counts when the facets face each other (n_s . n_m < 0) and the master facet comes within the
// search distance of the slave facet's plane.
//
// Cost: per slave facet, its candidate master facets, one clip and a Gauss rule per overlap (and
// for the dual space on a quad facet its 4 x 4 mass matrix).
#pragma once

#include <array>
#include <vector>

namespace htfeti {

/// The multiplier space of the mortar rows (see above).
enum class MortarBasis { dual, standard };

/// Boundary facets of one body (segments in 2D, triangles or quads in 3D) with their outward
/// unit normals; `nodes` are indices into the coordinate array (3 per node).
struct ContactSurface {
  int facet_nodes = 2;
  std::vector<int> nodes;                      ///< facet_nodes per facet (Gmsh order: cyclic)
  std::vector<std::array<double, 3>> normals;  ///< per facet, pointing out of its body
  int num_facets() const { return facet_nodes ? static_cast<int>(nodes.size()) / facet_nodes : 0; }
};

/// One inequality row of a slave node: n . (sum_j c_j u_j) <= weight * gap.
struct MortarRow {
  int slave_node = 0;
  std::array<double, 3> normal{0, 0, 0};  ///< n_i, unit, out of the slave body
  double weight = 0;  ///< W_i = sum_j D_ij (the measure phi_i covers where the master faces it)
  double area = 0;    ///< the integral of phi_i over all the slave surface (covered or not)
  double gap = 0;     ///< g_i / W_i: the weighted initial gap, in length units
  /// (node, c_j): D_ij on slave nodes, -M_ik on master nodes; ordered by node index.
  std::vector<std::pair<int, double>> entries;
};

/// The mortar rows of the slave surface against the master surface (dim 2 or 3). Rows only for
/// slave nodes whose support meets the master surface within `search_distance`
/// (W_i > 1e-10 times the node's own measure). Deterministic: the same rows on every rank.
std::vector<MortarRow> mortar_rows(int dim, const std::vector<double>& coords,
                                   const ContactSurface& slave, const ContactSurface& master,
                                   double search_distance, MortarBasis basis = MortarBasis::dual);

/// The largest facet diameter of a surface (the default search distance is twice the larger of
/// the two surfaces').
double largest_facet_diameter(const std::vector<double>& coords, const ContactSurface& s);

}  // namespace htfeti
