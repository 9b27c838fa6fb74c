// Cell topology (cell.hpp).
#include "htfeti/mesh/cell.hpp"

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

}  // namespace htfeti
