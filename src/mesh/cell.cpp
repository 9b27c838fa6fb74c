// Cell topology (cell.hpp).
#include "htfeti/mesh/cell.hpp"

namespace htfeti {

CellType parse_cell_type(const std::string& name) {
  return parse_name(kCellTypeNames, name, "element");
}

std::string to_string(CellType value) { return name_of(kCellTypeNames, value); }

int cell_dimension(CellType t) { return t == CellType::tri3 || t == CellType::quad4 ? 2 : 3; }
int cell_nodes(CellType t) {
  switch (t) {
    case CellType::tri3:
      return 3;
    case CellType::quad4:
      return 4;
    case CellType::tet4:
      return 4;
    case CellType::hex8:
      return 8;
  }
  return 0;
}
int vtk_cell_type(CellType t) {
  switch (t) {
    case CellType::tri3:
      return 5;
    case CellType::quad4:
      return 9;
    case CellType::tet4:
      return 10;
    case CellType::hex8:
      return 12;
  }
  return 0;
}

int cell_facet_count(CellType t) {
  switch (t) {
    case CellType::tri3:
      return 3;
    case CellType::quad4:
      return 4;
    case CellType::tet4:
      return 4;
    case CellType::hex8:
      return 6;
  }
  return 0;
}

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
