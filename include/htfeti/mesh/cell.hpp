// The cell types of htfeti's meshes and their topology: node counts, facets and the VTK type
// numbers. Node orders are Gmsh's (and VTK's). The finite elements on these cells are in
// fem/element.hpp; this header is what mesh/ needs without knowing the physics.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"

namespace htfeti {

enum class CellType : int { tri3, quad4, tet4, hex8 };
inline constexpr std::array<EnumName<CellType>, 4> kCellTypeNames{{{CellType::quad4, "quad4"},
                                                                   {CellType::tri3, "tri3"},
                                                                   {CellType::hex8, "hex8"},
                                                                   {CellType::tet4, "tet4"}}};
CellType parse_cell_type(const std::string& name);  // throws std::invalid_argument
std::string to_string(CellType type);
int cell_dimension(CellType type);
int cell_nodes(CellType type);
/// VTK cell type number (5 triangle, 9 quad, 10 tetra, 12 hexahedron).
int vtk_cell_type(CellType type);

/// Facets (boundary faces) of the cell, as local node indices: edges of 2D cells, faces of 3D
/// cells (triangles or quads). Used to find the domain boundary and to apply tractions.
int cell_facet_count(CellType type);
int cell_facet(CellType type, int facet, int* nodes);  // returns the number of nodes

/// The connected components of cells that share nodes: per node the smallest node index of its
/// component (union-find over the cells' nodes; `cells`: nodes_per_cell node indices per cell,
/// `nodes` nodes in all). Nodes of no cell are their own component.
std::vector<int> node_components(const std::vector<int>& cells, int nodes_per_cell, int nodes);

}  // namespace htfeti
