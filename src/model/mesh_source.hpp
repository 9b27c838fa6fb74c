// The mesh sources of GroupModel (group_model.cpp), private to model/.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "htfeti/mesh/mesh.hpp"
#include "htfeti/model/contact_pairs.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/parallel/comm.hpp"
#include "htfeti/partition/partition.hpp"

namespace htfeti {

// Where a GroupModel's subdomain meshes come from. GroupModel asks its source alone and never
// branches on the kind: a generated box split into boxes of subdomains (every rank generates its
// own, and equal subdomains are equal bit for bit), a whole mesh (read from a file, or a
// generated box made whole) split by METIS, or a mesh partitioned in advance, one file per part,
// of which every rank reads only its own (partitioned_source.cpp).
class MeshSource {
 public:
  virtual ~MeshSource() = default;
  virtual int dim() const = 0;
  virtual int num_subdomains() const = 0;
  virtual int num_clusters() const = 0;
  virtual int cluster_first(int c) const = 0;
  virtual long long num_nodes() const = 0;
  /// Nodes summed over the subdomains (a node once per subdomain holding a copy).
  virtual long long subdomain_nodes() const = 0;
  /// Subdomain s's mesh; a partitioned source holds only the subdomains of its rank's clusters.
  virtual SubdomainMesh mesh(int s) const = 0;
  /// The sizes of mesh(s) without building it, where the source knows them (false: build it).
  virtual bool mesh_counts(int s, Model::MeshCounts& counts) const = 0;
  /// The names of the groups of nodes, of boundary facets and of cells.
  virtual void groups(std::set<std::string>& nodes, std::set<std::string>& facets,
                      std::set<std::string>& cells) const = 0;
  /// The mesh this rank holds in memory (Model::held).
  virtual Model::MeshCounts held() const = 0;
  /// The report's description of the mesh and of its split.
  virtual void describe(const ProblemSpec& spec, nlohmann::json& j) const = 0;
  /// The surfaces of the contact conditions with a master group (contact between bodies), the
  /// same on every rank; false for a source of one body (a box split into boxes). Collective
  /// over the source's communicator for a partitioned mesh.
  virtual bool contact_surfaces(const ProblemSpec&, const Physics&, ContactSurfaces&) const {
    return false;
  }
};

/// Every cell of the mesh valid (fem/element.hpp: cell_is_valid): an inverted, self-intersecting
/// or degenerate element is refused with its tag, not solved with a wrong stiffness.
void check_cells(const Mesh& mesh, const std::string& file);

/// The source of a mesh that Gmsh partitioned in advance into one file per part (mesh.parts):
/// every rank reads the parts of its clusters only. Collective over comm; throws
/// std::invalid_argument on every rank for bad input.
std::unique_ptr<MeshSource> make_partitioned_source(const ProblemSpec& spec, const Comm& comm);

}  // namespace htfeti
