// Cell topology (cell.hpp).
#include "htfeti/mesh/cell.hpp"

#include <algorithm>

namespace htfeti {

CellType parse_cell_type(const std::string& name) {
  return parse_name(kCellTypeNames, name, "element");
}

std::string to_string(CellType value) { return name_of(kCellTypeNames, value); }

namespace {

// The topology of each cell type, indexed by CellType (tri3, quad4, tet4, hex8).
struct CellInfo {
  int dimension, nodes, vtk_type, facets;
};
constexpr CellInfo kCells[4] = {{2, 3, 5, 3}, {2, 4, 9, 4}, {3, 4, 10, 4}, {3, 8, 12, 6}};

const CellInfo& info(CellType t) { return kCells[static_cast<int>(t)]; }

}  // namespace

int cell_dimension(CellType t) { return info(t).dimension; }
int cell_nodes(CellType t) { return info(t).nodes; }
int vtk_cell_type(CellType t) { return info(t).vtk_type; }
int cell_facet_count(CellType t) { return info(t).facets; }

int cell_facet(CellType t, int f, int* nodes) {
  static const int tri[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  static const int quad[4][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}};
  static const int tet[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  static const int hex[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  switch (t) {
    case CellType::tri3:
      nodes[0] = tri[f][0], nodes[1] = tri[f][1];
      return 2;
    case CellType::quad4:
      nodes[0] = quad[f][0], nodes[1] = quad[f][1];
      return 2;
    case CellType::tet4:
      for (int i = 0; i < 3; ++i) nodes[i] = tet[f][i];
      return 3;
    case CellType::hex8:
      for (int i = 0; i < 4; ++i) nodes[i] = hex[f][i];
      return 4;
  }
  return 0;
}

std::vector<int> node_components(const std::vector<int>& cells, int nc, int nodes) {
  std::vector<int> parent(nodes);
  for (int k = 0; k < nodes; ++k) parent[k] = k;
  auto root = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  const size_t ne = nc > 0 ? cells.size() / nc : 0;
  for (size_t e = 0; e < ne; ++e) {
    const int* cn = cells.data() + e * nc;
    for (int a = 1; a < nc; ++a) {
      const int r0 = root(cn[0]), r1 = root(cn[a]);
      if (r0 != r1) parent[std::max(r0, r1)] = std::min(r0, r1);
    }
  }
  for (int k = 0; k < nodes; ++k) parent[k] = root(k);
  return parent;
}

}  // namespace htfeti
