// A problem as a user states it (DESIGN.md, "Problem files"), independent of how it was written
// down: the mesh source (a Gmsh file, or a generated box split into boxes of subdomains or by
// METIS), the physics, conditions on named groups and the decomposition. The problem-file
// reader (problem_file.hpp) fills one from TOML; the built-in cube-obstacle is one made in code;
// make_model() turns it into the Model the solver takes.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/box.hpp"
#include "htfeti/model/decomposition.hpp"
#include "htfeti/model/model.hpp"
#include "htfeti/model/mortar.hpp"
#include "htfeti/parallel/comm.hpp"
#include "htfeti/partition/partition.hpp"

namespace htfeti {

struct ProblemSpec {
  std::string path;  ///< the problem file
  /// [mesh] builtin = "poisson2d" | "membranes" | "membranes-coercive": a built-in problem, with
  /// elements = n and element = "q1" | "p1"; [decomposition] subdomains = N_s per side.
  std::string builtin;
  DecompositionOptions builtin_options;
  std::string mesh_file;  ///< resolved; empty for a generated box
  /// mesh.parts: a mesh that Gmsh partitioned in advance, one file per part (NAME_1.msh ...
  /// NAME_N.msh for mesh.parts = "NAME.msh", resolved); every rank reads only its own parts.
  std::string mesh_parts;
  BoxGridOptions box;  ///< generator = "box" (subdomains/cluster_size filled from below)
  Physics physics;
  std::string source = "0";  ///< Laplace source: a number or an expression in x, y, z
  struct Dirichlet {
    std::string group;
    std::array<double, 3> value{0, 0, 0};
    std::vector<int> components;  ///< empty: all
  };
  struct Load {
    std::string group;
    enum Kind { traction, source, force } kind = traction;
    std::array<double, 3> value{0, 0, 0};
  };
  struct Contact {
    std::string group;
    std::array<double, 3> direction{0, 0, -1};
    std::string gap = "0";
    /// Tresca friction on the condition (friction = { law = "tresca", bound = g }): the slip
    /// bound g per unit area (force per area) of the tangential traction; < 0: frictionless.
    double slip_bound = -1;
    /// Coulomb friction (friction = { law = "coulomb", coefficient = mu }): mu >= 0; < 0: none.
    double friction_coefficient = -1;
    /// Contact between bodies: the master group (empty: a rigid obstacle, `direction`, `gap`).
    /// `group` is then the slave surface, with mortar rows (model/mortar.hpp).
    std::string master;
    /// Contact between bodies: master facets farther than this from a slave facet's plane are
    /// not paired with it; 0: twice the largest facet diameter of the two surfaces.
    double search_distance = 0;
    /// Contact between bodies: the mortar rows' multiplier space (multipliers = "dual" |
    /// "standard"; model/mortar.hpp).
    MortarBasis multipliers = MortarBasis::dual;
  };
  std::vector<Dirichlet> dirichlet;
  std::vector<Load> loads;
  std::vector<Contact> contact;
  /// One number (METIS) or one per axis (generated box); empty for mesh.parts when not given (the
  /// number of parts).
  std::vector<int> subdomains{1};
  int cluster_size = 1;
  Glue glue = Glue::averages;
  /// METIS's objective when a mesh is split (not a box split into boxes).
  PartitionObjective partition_objective = PartitionObjective::automatic;
  /// How a METIS split forms the clusters (cluster_size > 1; partition.hpp).
  ClusterSplit cluster_split = ClusterSplit::mesh;
  /// METIS's random seed when a mesh is split (METIS_OPTION_SEED; partition.hpp).
  int partition_seed = kDefaultPartitionSeed;
  /// A METIS split with a coefficient field: facets across which the coefficient changes by more
  /// than this factor are jumps, and no subdomain straddles one (partition.hpp); 0: off.
  double partition_jump_ratio = kDefaultJumpRatio;
  /// The shape of a METIS split's parts: compact, or METIS's as they are (partition.hpp).
  PartitionShape partition_shape = PartitionShape::compact;
};

/// The cube-obstacle benchmark (DESIGN.md; the paper's Table 4, ESPRESO's former obstacle
/// benchmark): the cube [0,100]^3 of hex8 elements (nx, ny, nz), clamped on x = 0, under its own
/// weight (density 7850, gravity -9.8066 in z), E = 2.1e7, nu = 0.3, in frictionless contact on
/// z = 0 with a rigid obstacle u_z >= -amplitude sin(pi x / 50) (direction (0,0,-1), gap
/// amplitude sin(pi x / 50)); subdomains (sx, sy, sz), clusters of m x m x m.
ProblemSpec cube_obstacle_spec(const std::vector<int>& elements, const std::vector<int>& subdomains,
                               int cluster_size, double amplitude = 1.0,
                               CellType cell = CellType::hex8);

/// Builds the model (reads and partitions the mesh). Throws std::invalid_argument for input
/// that does not fit (missing groups, sizes). comm: the ranks that will solve it, which a
/// partitioned mesh (mesh.parts) is read by, each its own parts (null: MPI_COMM_WORLD); collective
/// over comm for such a mesh.
std::unique_ptr<Model> make_model(const ProblemSpec& spec, const Comm* comm = nullptr);

}  // namespace htfeti
