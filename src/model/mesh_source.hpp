// The mesh sources of GroupModel (group_model.cpp), private to model/.
#pragma once

#include <map>
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
// generated box made whole) split by METIS (on one rank: MetisSplit; on several: ScatteredSplit,
// rank 0 splits and sends each rank its subdomains), or a mesh partitioned in advance, one file
// per part, of which every rank reads only its own (partitioned_source.cpp).
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

/// A source whose rank holds only the subdomains of its own clusters (a partitioned mesh, or a
/// whole mesh split on rank 0): their meshes, and of every subdomain its counts, and the names of
/// the groups over the whole mesh.
class HeldSubdomains : public MeshSource {
 public:
  explicit HeldSubdomains(const Comm& comm) : comm_(comm) {}
  SubdomainMesh mesh(int s) const override {
    auto it = meshes_.find(s);
    if (it == meshes_.end())
      throw std::logic_error("subdomain " + std::to_string(s) + " is not held by rank " +
                             std::to_string(comm_.rank()) + " (" + where() + ")");
    return it->second;
  }
  bool mesh_counts(int s, Model::MeshCounts& counts) const override {
    counts = counts_.at(s);
    return true;
  }
  void groups(std::set<std::string>& nodes, std::set<std::string>& facets,
              std::set<std::string>& cells) const override {
    nodes.insert(node_names_.begin(), node_names_.end());
    facets.insert(facet_names_.begin(), facet_names_.end());
    cells.insert(cell_names_.begin(), cell_names_.end());
  }
  Model::MeshCounts held() const override {
    Model::MeshCounts h;
    for (const auto& [s, m] : meshes_)
      h.points += m.num_nodes(), h.cells += m.num_cells(), h.corners += m.cells.size();
    return h;
  }

 protected:
  /// Where the meshes came from, for the error of asking for another rank's subdomain.
  virtual std::string where() const = 0;
  Comm comm_;
  std::map<int, SubdomainMesh> meshes_;
  std::vector<Model::MeshCounts> counts_;                           ///< per subdomain
  std::vector<std::string> node_names_, facet_names_, cell_names_;  ///< sorted
};

/// Runs a step of this rank's own work and agrees on its failure with every rank of comm: bad
/// input (std::invalid_argument) is thrown as bad input everywhere, anything else as a runtime
/// error.
template <class F>
void agreed(const Comm& comm, F&& step) {
  std::string error;
  bool input = false;
  try {
    step();
  } catch (const std::invalid_argument& e) {
    error = e.what(), input = true;
  } catch (const std::exception& e) {
    error = e.what();
  }
  comm.agree(error, input);
}

/// Every cell of the mesh valid (fem/element.hpp: cell_is_valid): an inverted, self-intersecting
/// or degenerate element is refused with its tag, not solved with a wrong stiffness.
void check_cells(const Mesh& mesh, const std::string& file);

/// The source of a mesh that Gmsh partitioned in advance into one file per part (mesh.parts):
/// every rank reads the parts of its clusters only. Collective over comm; throws
/// std::invalid_argument on every rank for bad input.
std::unique_ptr<MeshSource> make_partitioned_source(const ProblemSpec& spec, const Comm& comm);

}  // namespace htfeti
