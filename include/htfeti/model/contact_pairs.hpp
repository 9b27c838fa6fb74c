// Contact between bodies (the [[contact]] conditions with a master group): the checks of the
// pairs, the mortar rows of each (mortar.hpp) and their hand-over to the subdomains.
//
// Built once from the contact surfaces (ContactSurfaces: the facets of the groups, and of the
// nodes they touch the coordinates, copies and Dirichlet components), which a whole mesh gives
// directly (contact_surfaces below) and a mesh partitioned in advance gathers from its parts
// (model/partitioned_source.cpp). Every rank builds the same rows from the same surfaces: the
// contact search and the integrals run on the surfaces only. A row of slave node i is
//     n_i . (sum_j D_ij avg u_j - sum_k M_ik avg u_k) <= W_i gap_i
// (feti/input.hpp: ContactRow); each subdomain gets the part of every row on its nodes, with
// the row's norm over all its nodes' copies (which no subdomain alone could compute).
//
// Laplace pairs (the paper's two membranes as two bodies) use the condition's direction (+1 or
// -1) instead of the normal and its gap expression at the slave node instead of the geometric
// gap: direction (u_slave - u_master) <= gap, weakly.
#pragma once

#include <array>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/mesh.hpp"
#include "htfeti/mesh/subdomain_mesh.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/partition/partition.hpp"

namespace htfeti {

/// The coordinate axis least aligned with n (the lowest on ties): the reference from which the
/// first tangent of a contact condition's friction rows is made in 3D.
std::array<double, 3> reference_axis(const std::array<double, 3>& n);
/// t1 = (a - (a.n) n) / |a - (a.n) n|, the first tangent of a friction row in 3D (t2 = n x t1):
/// continuous in n wherever n is not parallel to a, so one reference axis per condition gives
/// tangent bases continuous over its surface.
std::array<double, 3> friction_tangent(const std::array<double, 3>& n,
                                       const std::array<double, 3>& a);

/// The tangential rows of a 3D friction node whose own displacement a Dirichlet condition
/// fixes along some coordinate axes (`fixed[d]`). A fixed axis e_d that is not the normal
/// (|n_d| < 1 - 1e-12) leaves the node free to slip only along t = n x e_d / |n x e_d|: a row
/// along the other tangent would repeat the Dirichlet row (with the normal row), and as the
/// second half of a disc it would take an arbitrary share of the bound (on a symmetry plane,
/// the stick zone of a sphere came out with slipping nodes on the plane). Then one row along t,
/// an interval (`rows` = 1, `tangent` = t); two such axes: no tangential row (`rows` = 0); none:
/// the disc of `rows` = 2 along `tangent` = the condition's t1 and n x t1.
struct FrictionRows {
  int rows = 2;
  std::array<double, 3> tangent{0, 0, 0};
};
FrictionRows friction_rows_at(const std::array<double, 3>& n, const std::array<double, 3>& t1,
                              const std::array<bool, 3>& fixed);

/// What the contact rows need of the mesh, indexed by "surface node": the facets of the groups
/// that contact conditions with a master name, with their outward normals and the bodies they
/// lie on; and for every node those facets touch, its coordinates, global id, the number of
/// subdomains holding a copy, the first of them (the copies' canonical order) and the
/// components that Dirichlet conditions hold.
struct ContactSurfaces {
  int dim = 3;
  int num_bodies = 1;
  std::vector<double> coords;        ///< 3 per surface node
  std::vector<long long> global;     ///< surface node -> global node; empty: the same number
  std::vector<int> copies, owner;    ///< per surface node
  std::vector<unsigned char> fixed;  ///< per surface node: bit c when component c is held
  struct Group {
    ContactSurface surface;   ///< facets in surface nodes, normals out of their bodies
    std::vector<int> bodies;  ///< the bodies its facets lie on, sorted
    std::string error;        ///< why it is no contact surface ("group 'a' has ..."), or empty
  };
  std::map<std::string, Group> groups;
  long long global_node(int k) const { return global.empty() ? k : global[k]; }
};

/// The pieces from which contact_surfaces builds a group, shared with the gathering of the
/// surfaces of a partitioned mesh. The errors name the group and the facet by node tags.
std::string no_facets_error(const std::string& group, int dim);
std::string not_boundary_error(const std::string& group, long long tag0, long long tag1);
/// True when the cell's nc nodes include the facet's fn nodes.
bool cell_holds_facet(const int* cell, int nc, const int* facet, int fn);
/// The unit normal of facet v (fn node numbers into coords, 3 per node, cyclic) pointing away
/// from the centroid of the cell it bounds (nc node numbers).
std::array<double, 3> outward_normal(int dim, const double* coords, const int* v, int fn,
                                     const int* cell, int nc);
/// Per node, bit c set where a Dirichlet condition of spec holds component c (its group looked
/// up among node_groups; groups not there hold nothing).
std::vector<unsigned char> fixed_components(
    const ProblemSpec& spec, int dofs_per_node,
    const std::map<std::string, std::vector<int>>& node_groups, int nodes);

/// The contact surfaces of every condition with a master group, from a whole mesh and its
/// partition (the surface nodes: the groups' nodes, in the mesh's order).
ContactSurfaces contact_surfaces(const ProblemSpec& spec, const Physics& physics, const Mesh& mesh,
                                 const MeshPartition& part);

class ContactPairs {
 public:
  ContactPairs() = default;
  /// The rows of every contact condition with a master group. Throws std::invalid_argument
  /// naming the condition: a group without boundary facets, slave and master on one body, a
  /// pair given twice, no slave facet facing the master within the search distance.
  ContactPairs(const ProblemSpec& spec, const Physics& physics, const ContactSurfaces& surfaces);
  bool empty() const { return rows_.empty(); }
  /// Appends to in.contact the parts of the rows on the nodes of subdomain mesh m.
  void add_rows(const SubdomainMesh& m, SubdomainInput& in) const;
  /// What the report and the dry run say of condition c: rows, the search distance used, the
  /// bodies of the two groups.
  nlohmann::json describe(int condition) const;

 private:
  struct Row {
    int condition = 0;
    long long slave = 0;  ///< the slave node (global)
    std::array<double, 3> normal{0, 0, 0}, tangent{0, 0, 0};
    int tangent_rows = 2;  ///< 3D friction: FrictionRows::rows
    double weight = 0, gap = 0, norm_sq = 0;
    int owner = 0;
  };
  struct Entry {
    long long node;  ///< global node
    int row;
    double coefficient;
    bool slave;
  };
  std::vector<Row> rows_;
  std::vector<Entry> by_node_;  ///< sorted by node, then row
  std::vector<double> coords_;  ///< of the slave nodes' rows (3 per row)
  struct Info {
    long long rows = 0;
    double search_distance = 0;
    MortarBasis multipliers = MortarBasis::dual;
    std::vector<int> slave_bodies, master_bodies;
    double slip_bound = -1, friction_coefficient = -1;
  };
  std::vector<Info> info_;  ///< per condition (empty for obstacles)
};

}  // namespace htfeti
