// The mesh of one subdomain as the partition hands it to the rest of the pipeline: local nodes
// (with their global ids and coordinates), cells in local node numbers, which subdomains share
// each node (the "copies", in the partition's canonical order), whether a node lies on the
// boundary of the whole domain, and the named groups restricted to this subdomain.
//
// Every subdomain has its own copy of its nodes (FETI): a node on an interface appears in the
// SubdomainMesh of every subdomain that shares it, with the same global id, coordinates and list
// of copies.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "htfeti/mesh/cell.hpp"

namespace htfeti {

struct SubdomainMesh {
  int id = 0;       ///< global subdomain id
  int cluster = 0;  ///< global cluster id
  int dim = 2;
  CellType type = CellType::quad4;
  std::vector<double> coords;          ///< 3 per local node
  std::vector<long long> global_node;  ///< local node -> global node id
  std::vector<int> cells;              ///< cell_nodes(type) local node indices per cell
  /// Generated grids: cell e is a translate of cell e % uniform_period (element matrices are
  /// computed for the first uniform_period cells only); 0 for a general mesh.
  int uniform_period = 0;
  /// Generated grids: the grid spacing per direction (0 for a general mesh). Element matrices
  /// are computed on the cell's offsets from its first node in whole multiples of it, so every
  /// subdomain of a box gets the same element matrices bit for bit (its coordinates, rounded
  /// differently at each position, are left for loads and output).
  double uniform_spacing[3] = {0, 0, 0};
  /// Copies of local node k: copy_list[copy_offset[k] .. copy_offset[k+1]), subdomain ids in the
  /// partition's canonical order (the same list in every subdomain that holds the node).
  std::vector<int> copy_offset, copy_list;
  std::vector<char> on_boundary;  ///< node lies on the boundary of the whole domain
  /// Named node groups (Gmsh physical groups, box faces x0 x1 y0 y1 z0 z1): local nodes.
  std::map<std::string, std::vector<int>> node_groups;
  /// Named boundary facet groups: local node indices, facet_nodes per facet (2, 3 or 4).
  struct FacetGroup {
    int facet_nodes = 0;
    std::vector<int> nodes;
  };
  std::map<std::string, FacetGroup> facet_groups;
  /// Named cell groups (volume physical groups): local cell indices.
  std::map<std::string, std::vector<int>> cell_groups;

  int num_nodes() const { return static_cast<int>(global_node.size()); }
  int num_cells() const { return static_cast<int>(cells.size()) / cell_nodes(type); }
  int num_copies(int k) const { return copy_offset[k + 1] - copy_offset[k]; }
  const int* copies(int k) const { return copy_list.data() + copy_offset[k]; }
};

}  // namespace htfeti
