// A problem as htfeti solves it (DESIGN.md, "Architecture"): a mesh source (a generated box, or a
// Gmsh mesh split by METIS), the physics, conditions on named groups and the decomposition into
// subdomains and clusters. The model hands the FETI stage what it needs, one subdomain at a time
// (input(s)), and the writers the subdomain meshes (mesh(s)); a rank asks only for its own
// subdomains, so a generated box is never built whole.
//
// The built-in benchmarks (poisson2d, membranes, membranes-coercive) are models on generated
// boxes with conditions of their own (make_builtin_model); problem files give models with
// conditions on named groups (problem_file.hpp, make_model).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/subdomain_mesh.hpp"
#include "htfeti/model/decomposition.hpp"

namespace htfeti {

class Model {
 public:
  virtual ~Model() = default;
  const Physics& physics() const { return physics_; }
  int dim() const { return physics_.dim; }
  Glue glue() const { return glue_; }
  virtual int num_subdomains() const = 0;
  virtual int num_clusters() const = 0;
  /// Subdomains of cluster c: [cluster_first(c), cluster_first(c + 1)).
  virtual int cluster_first(int c) const = 0;
  virtual long long num_nodes() const = 0;
  /// Primal unknowns of the decomposed problem (every subdomain with its own copies).
  virtual long long primal_dimension() const = 0;
  virtual SubdomainMesh mesh(int s) const = 0;
  /// The sizes of mesh(s): points, cells and cell corners (the writers place each subdomain's
  /// values by them). Generated boxes know them by arithmetic; the default builds the mesh.
  struct MeshCounts {
    long long points = 0, cells = 0, corners = 0;
  };
  virtual MeshCounts mesh_counts(int s) const;
  /// The mesh this rank holds in memory for the whole solve: the whole mesh where it was read or
  /// generated whole (split by METIS), the parts of its own clusters where the mesh was
  /// partitioned in advance (mesh.parts), nothing for generated boxes (made subdomain by
  /// subdomain when needed).
  virtual MeshCounts held() const { return {}; }
  /// The load of a Laplace problem at a point (unused for elasticity).
  virtual SourceFunction source() const { return {}; }
  /// Adds the subdomain's boundary loads to f and its Dirichlet dofs and contact rows.
  virtual void apply_conditions(const SubdomainMesh& mesh, SubdomainInput& in) const = 0;
  /// Whether the problem has contact conditions (inequalities).
  virtual bool has_contact() const = 0;
  /// The contact conditions in order (the `condition` of their rows): the group and the master
  /// group (empty for a rigid obstacle).
  struct ContactCondition {
    std::string group, master;
  };
  virtual std::vector<ContactCondition> contact_conditions() const { return {}; }
  /// The report's description of the problem (mesh, physics, decomposition).
  virtual nlohmann::json describe() const = 0;

  FetiLayout layout() const;
  /// Generates, assembles and describes subdomain s for the FETI stage. Thread-safe.
  SubdomainInput input(int s) const;

 protected:
  Physics physics_;
  Glue glue_ = Glue::averages;
};

class BoxGrid;
/// Model::mesh_counts of every subdomain of a generated box (all have the same sizes).
Model::MeshCounts box_mesh_counts(const BoxGrid& grid);

/// The built-in 2D benchmarks (DESIGN.md, "Built-in problems") on the generated squares.
std::unique_ptr<Model> make_builtin_model(const DecompositionOptions& options);

}  // namespace htfeti
