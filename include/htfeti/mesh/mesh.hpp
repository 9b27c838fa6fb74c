// A whole mesh read from a file (Gmsh .msh 2.2 or 4.1, ASCII or binary, through the Gmsh SDK):
// one volume cell type (tri3 | quad4 in 2D, tet4 | hex8 in 3D), node coordinates, and the named
// physical groups as node sets, boundary facet sets (groups of dimension dim - 1) and cell sets
// (groups of dimension dim). Only nodes that belong to a cell are kept; they are numbered
// 0..n-1 in the order of their Gmsh tags (the global node ids of the pipeline).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "htfeti/mesh/cell.hpp"

namespace htfeti {

struct Mesh {
  int dim = 2;
  CellType type = CellType::tri3;
  std::vector<double> coords;                           ///< 3 per node
  std::vector<int> cells;                               ///< cell_nodes(type) node indices per cell
  std::map<std::string, std::vector<int>> node_groups;  ///< sorted node indices
  struct FacetGroup {
    int facet_nodes = 0;
    std::vector<int> nodes;  ///< facet_nodes node indices per facet
  };
  std::map<std::string, FacetGroup> facet_groups;
  std::map<std::string, std::vector<int>> cell_groups;  ///< cell indices
  std::vector<std::size_t> cell_tags;                   ///< the file's element tag of each cell
  std::vector<std::size_t> node_tags;                   ///< the file's node tag of each node
  /// Partitions of the mesh the file belongs to (Gmsh's $PartitionedEntities; 0: not partitioned).
  int partitions = 0;
  int num_nodes() const { return static_cast<int>(coords.size() / 3); }
  int num_cells() const { return static_cast<int>(cells.size()) / cell_nodes(type); }
};

struct GmshReadOptions {
  /// Skip physical groups without a name (in one part of a partitioned mesh Gmsh adds unnamed
  /// groups of its own, for the partition boundaries, whose numbers may repeat the user's).
  bool named_groups_only = false;
};

/// Reads a Gmsh mesh. Throws std::invalid_argument naming the file and the problem (missing,
/// unreadable, malformed, no supported cells, mixed cell types). Unnamed groups are named by
/// their number unless options.named_groups_only.
Mesh read_gmsh(const std::string& path, const GmshReadOptions& options = {});

}  // namespace htfeti
