#include <gmsh.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <unordered_map>

#include "htfeti/mesh/mesh.hpp"

namespace htfeti {

namespace {

// Gmsh element type numbers of the linear cells and facets htfeti supports.
int gmsh_cell_nodes(int type) {
  switch (type) {
    case 1:  // line2
      return 2;
    case 2:  // tri3
      return 3;
    case 3:  // quad4
      return 4;
    case 4:  // tet4
      return 4;
    case 5:  // hex8
      return 8;
    case 15:  // point
      return 1;
    default:
      return 0;
  }
}

CellType cell_type_of(int gmsh_type) {
  switch (gmsh_type) {
    case 2:
      return CellType::tri3;
    case 3:
      return CellType::quad4;
    case 4:
      return CellType::tet4;
    default:
      return CellType::hex8;
  }
}

// Names of Gmsh element types for messages. (Not gmsh::model::mesh::getElementProperties: it runs
// Gmsh's own Eigen code, whose template instances clash with ours in sanitizer builds.)
std::string gmsh_type_name(int type) {
  static const char* names[] = {"?",      "line2",   "tri3",  "quad4", "tet4",  "hex8",
                                "prism6", "pyr5",    "line3", "tri6",  "quad9", "tet10",
                                "hex27",  "prism18", "pyr14", "point", "quad8", "hex20"};
  if (type >= 0 && type < static_cast<int>(sizeof(names) / sizeof(names[0]))) return names[type];
  return "type " + std::to_string(type);
}

std::mutex gmsh_mutex;  // the Gmsh SDK keeps global state

// A node tag that an ASCII .msh file gives twice in its $Nodes section, or 0 (also for binary
// files). The Gmsh SDK keeps one of the two points without a word, so a repeated tag shows only
// here. MSH 2: one "tag x y z" line per node; MSH 4: blocks of "dim entity parametric count",
// then count tags, then count coordinate lines. Costs one pass over the node section.
std::size_t repeated_node_tag(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // $MeshFormat
  double version = 0;
  int file_type = 1;
  if (!(in >> version >> file_type) || file_type != 0) return 0;
  while (std::getline(in, line) && line.rfind("$Nodes", 0) != 0) {
  }
  if (!in) return 0;
  std::vector<std::size_t> tags;
  if (version < 3) {
    long long count = 0;
    if (!(in >> count) || count < 0) return 0;
    tags.reserve(static_cast<std::size_t>(count));
    std::getline(in, line);
    for (long long i = 0; i < count && std::getline(in, line); ++i)
      tags.push_back(std::strtoull(line.c_str(), nullptr, 10));
  } else {
    long long blocks = 0, count = 0, min_tag = 0, max_tag = 0;
    if (!(in >> blocks >> count >> min_tag >> max_tag) || count < 0) return 0;
    tags.reserve(static_cast<std::size_t>(count));
    for (long long b = 0; b < blocks; ++b) {
      long long dim = 0, entity = 0, parametric = 0, n = 0;
      if (!(in >> dim >> entity >> parametric >> n)) return 0;
      for (long long i = 0; i < n; ++i) {
        std::size_t tag = 0;
        if (!(in >> tag)) return 0;
        tags.push_back(tag);
      }
      std::getline(in, line);
      for (long long i = 0; i < n && std::getline(in, line); ++i) {
      }
    }
  }
  std::sort(tags.begin(), tags.end());
  const auto twice = std::adjacent_find(tags.begin(), tags.end());
  return twice == tags.end() ? 0 : *twice;
}

// The number of partitions a file of MSH 4 declares in its $PartitionedEntities section (one part
// of a partitioned mesh), or 0. The Gmsh SDK keeps it to itself (4.8 has no call for it). Reads
// the sections before $Nodes only; in a binary file the count is a size_t, in ASCII a number.
int partition_count(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string header;
  std::getline(in, header);  // $MeshFormat
  double version = 0;
  int file_type = 0, data_size = 0;
  if (!(in >> version >> file_type >> data_size) || version < 4) return 0;
  const std::string tag = "$PartitionedEntities", stop = "$Nodes";
  std::string window;
  char ch;
  while (in.get(ch)) {
    window.push_back(ch);
    if (window.size() > tag.size() + 1) window.erase(0, window.size() - tag.size() - 1);
    const bool line_start = window.size() > tag.size() && window[0] == '\n';
    if (line_start && window.compare(1, stop.size(), stop) == 0) return 0;
    if (line_start && window.compare(1, tag.size(), tag) == 0) {
      in.get(ch);  // the newline after the section name
      if (file_type == 0) {
        long long n = 0;
        return (in >> n) && n > 0 && n < (1LL << 31) ? static_cast<int>(n) : 0;
      }
      std::uint64_t n = 0;
      if (data_size != 8 || !in.read(reinterpret_cast<char*>(&n), 8)) return 0;
      return n > 0 && n < (1ULL << 31) ? static_cast<int>(n) : 0;
    }
  }
  return 0;
}

// The steps of read_gmsh on the model the Gmsh SDK has open. Node and cell numbers of the mesh
// are positions: nodes in increasing tag order, cells in Gmsh's order.
using TagIndex = std::unordered_map<std::size_t, int>;

// The cells of the highest dimension (3, else 2): their type, the node tags of each (returned)
// and their Gmsh tags (mesh.cell_tags).
std::vector<std::size_t> read_cells(const std::string& path, Mesh& mesh) {
  int dim = -1;
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> tags, nodes;
  for (int d = 3; d >= 2 && dim < 0; --d) {
    gmsh::model::mesh::getElements(types, tags, nodes, d, -1);
    for (size_t i = 0; i < types.size(); ++i)
      if (!tags[i].empty()) dim = d;
  }
  if (dim < 0) throw std::invalid_argument("mesh file '" + path + "' has no 2D or 3D cells");
  int type = -1;
  for (size_t i = 0; i < types.size(); ++i) {
    if (tags[i].empty()) continue;
    const bool ok = dim == 2 ? (types[i] == 2 || types[i] == 3) : (types[i] == 4 || types[i] == 5);
    if (!ok)
      throw std::invalid_argument("mesh file '" + path + "' has cells of type '" +
                                  gmsh_type_name(types[i]) +
                                  "'; htfeti supports linear tri3 and quad4 (2D), tet4 and hex8 "
                                  "(3D)");
    if (type >= 0 && type != types[i])
      throw std::invalid_argument("mesh file '" + path +
                                  "' mixes cell types; use one of tri3/quad4 (2D) or "
                                  "tet4/hex8 (3D)");
    type = types[i];
  }
  mesh.dim = dim;
  mesh.type = cell_type_of(type);
  std::vector<std::size_t> cell_node_tags;
  for (size_t i = 0; i < types.size(); ++i) {
    if (types[i] != type) continue;
    cell_node_tags.insert(cell_node_tags.end(), nodes[i].begin(), nodes[i].end());
    mesh.cell_tags.insert(mesh.cell_tags.end(), tags[i].begin(), tags[i].end());
  }
  return cell_node_tags;
}

// The nodes the cells use, numbered by tag (mesh.coords), and the cells in those numbers
// (mesh.cells). Returns the tag -> node map.
TagIndex read_nodes(const std::string& path, const std::vector<std::size_t>& cell_node_tags,
                    Mesh& mesh) {
  std::vector<std::size_t> node_tags;
  std::vector<double> coord, param;
  gmsh::model::mesh::getNodes(node_tags, coord, param, -1, -1, false, false);
  std::vector<std::size_t> used(cell_node_tags);
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  TagIndex index;
  index.reserve(used.size() * 2);
  for (size_t i = 0; i < used.size(); ++i) index[used[i]] = static_cast<int>(i);
  mesh.node_tags = used;
  mesh.coords.assign(3 * used.size(), 0.0);
  std::vector<char> seen(used.size(), 0);
  for (size_t i = 0; i < node_tags.size(); ++i) {
    auto it = index.find(node_tags[i]);
    if (it == index.end()) continue;
    for (int d = 0; d < 3; ++d) mesh.coords[3 * it->second + d] = coord[3 * i + d];
    seen[it->second] = 1;
  }
  if (std::find(seen.begin(), seen.end(), 0) != seen.end())
    throw std::invalid_argument("mesh file '" + path + "' has cells with undefined nodes");
  mesh.cells.resize(cell_node_tags.size());
  for (size_t i = 0; i < cell_node_tags.size(); ++i) mesh.cells[i] = index.at(cell_node_tags[i]);
  return index;
}

// The elements of one physical group `name` (dimension gd) on one of its entities: cells of the
// mesh's dimension into mesh.cell_groups, facets one dimension lower into mesh.facet_groups.
void read_group_entity(const std::string& path, const std::string& name, int gd, int entity,
                       const TagIndex& index, const TagIndex& cell_index, Mesh& mesh) {
  std::vector<int> et;
  std::vector<std::vector<std::size_t>> etags, enodes;
  gmsh::model::mesh::getElements(et, etags, enodes, gd, entity);
  for (size_t i = 0; i < et.size(); ++i) {
    if (gd == mesh.dim) {
      auto& cg = mesh.cell_groups[name];
      for (std::size_t t : etags[i]) {
        auto it = cell_index.find(t);
        if (it != cell_index.end()) cg.push_back(it->second);
      }
    } else if (gd == mesh.dim - 1) {
      const int fn = gmsh_cell_nodes(et[i]);
      if (fn == 0) continue;
      auto& fg = mesh.facet_groups[name];
      if (fg.facet_nodes != 0 && fg.facet_nodes != fn)
        throw std::invalid_argument("mesh file '" + path + "': boundary group '" + name +
                                    "' mixes facet types");
      fg.facet_nodes = fn;
      for (std::size_t t : enodes[i]) {
        auto it = index.find(t);
        if (it == index.end())
          throw std::invalid_argument("mesh file '" + path + "': boundary group '" + name +
                                      "' has a facet off the mesh");
        fg.nodes.push_back(it->second);
      }
    }
  }
}

// The physical groups: nodes of every group (mesh.node_groups, unnamed groups by their
// number), and cells or facets by read_group_entity.
void read_groups(const std::string& path, const TagIndex& index, bool named_only, Mesh& mesh) {
  TagIndex cell_index;
  for (size_t i = 0; i < mesh.cell_tags.size(); ++i)
    cell_index[mesh.cell_tags[i]] = static_cast<int>(i);
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups, -1);
  for (const auto& [gd, gt] : groups) {
    std::string name;
    gmsh::model::getPhysicalName(gd, gt, name);
    if (name.empty() && named_only) continue;
    if (name.empty()) name = std::to_string(gt);
    std::vector<std::size_t> gnodes;
    std::vector<double> gcoord;
    gmsh::model::mesh::getNodesForPhysicalGroup(gd, gt, gnodes, gcoord);
    auto& ng = mesh.node_groups[name];
    for (std::size_t t : gnodes) {
      auto it = index.find(t);
      if (it != index.end()) ng.push_back(it->second);
    }
    std::sort(ng.begin(), ng.end());
    ng.erase(std::unique(ng.begin(), ng.end()), ng.end());
    std::vector<int> ents;
    gmsh::model::getEntitiesForPhysicalGroup(gd, gt, ents);
    for (int e : ents) read_group_entity(path, name, gd, e, index, cell_index, mesh);
  }
}

}  // namespace

Mesh read_gmsh(const std::string& path, const GmshReadOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::invalid_argument("mesh file '" + path + "' does not exist or is not a file");
  {
    std::ifstream probe(path);
    if (!probe) throw std::invalid_argument("mesh file '" + path + "' cannot be read");
    std::string first;
    std::getline(probe, first);
    if (first.rfind("$MeshFormat", 0) != 0)
      throw std::invalid_argument("mesh file '" + path +
                                  "' is not a Gmsh .msh file (no $MeshFormat header)");
  }
  if (const std::size_t tag = repeated_node_tag(path))
    throw std::invalid_argument("mesh file '" + path + "': node " + std::to_string(tag) +
                                " is given twice in $Nodes (which coordinates are meant?)");
  std::lock_guard<std::mutex> lock(gmsh_mutex);
  Mesh mesh;
  mesh.partitions = partition_count(path);
  // gmsh::initialize() sets OpenMP's thread count to its own default (1): restore ours after.
  const int threads = omp_get_max_threads();
  gmsh::initialize();
  struct Finalize {
    int threads;
    ~Finalize() {
      gmsh::finalize();
      omp_set_num_threads(threads);
    }
  } finalize{threads};
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("General.Verbosity", 0);
  try {
    gmsh::open(path);
    const std::vector<std::size_t> cell_node_tags = read_cells(path, mesh);
    const TagIndex index = read_nodes(path, cell_node_tags, mesh);
    read_groups(path, index, options.named_groups_only, mesh);
  } catch (const std::invalid_argument&) {
    throw;
  } catch (const std::exception& e) {
    throw std::invalid_argument("mesh file '" + path + "' could not be read: " + e.what());
  } catch (...) {
    throw std::invalid_argument("mesh file '" + path + "' could not be read");
  }
  if (mesh.cells.empty()) throw std::invalid_argument("mesh file '" + path + "' has no cells");
  return mesh;
}

}  // namespace htfeti
