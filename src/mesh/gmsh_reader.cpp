#include <dlfcn.h>
#include <gmshc.h>  // declarations only: the SDK is loaded at run time (GmshSdk)
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <type_traits>
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

// Names of Gmsh element types for messages. (Not the SDK's getElementProperties: it runs
// Gmsh's own Eigen code, whose template instances clash with ours in sanitizer builds.)
std::string gmsh_type_name(int type) {
  static const char* names[] = {"?",      "line2",   "tri3",  "quad4", "tet4",  "hex8",
                                "prism6", "pyr5",    "line3", "tri6",  "quad9", "tet10",
                                "hex27",  "prism18", "pyr14", "point", "quad8", "hex20"};
  if (type >= 0 && type < static_cast<int>(sizeof(names) / sizeof(names[0]))) return names[type];
  return "type " + std::to_string(type);
}

std::mutex gmsh_mutex;  // the Gmsh SDK keeps global state

// The Gmsh SDK, loaded when the first mesh file is read (dlopen, RTLD_LOCAL), not linked.
// Its library brings some 120 others (OpenCASCADE, FLTK, X11, image codecs); linked, their
// symbols were searched at every start of every process, Open MPI's own start among them: 0.23
// s per process whether it read a mesh or not, and some 60 MB of resident memory. Loaded here,
// a run that reads a mesh pays about 0.18 s more than linked (bench/startup_time.py). The C
// API (gmshc.h) is used: plain functions that dlsym finds by name; arrays it returns are freed
// with its own free. HTFETI_GMSH_FUNCTIONS lists the functions htfeti calls: (member of
// GmshSdk, name in the library).
#define HTFETI_GMSH_FUNCTIONS(X)                                           \
  X(free, gmshFree)                                                        \
  X(initialize, gmshInitialize)                                            \
  X(finalize, gmshFinalize)                                                \
  X(open, gmshOpen)                                                        \
  X(set_number, gmshOptionSetNumber)                                       \
  X(get_elements, gmshModelMeshGetElements)                                \
  X(get_nodes, gmshModelMeshGetNodes)                                      \
  X(get_physical_groups, gmshModelGetPhysicalGroups)                       \
  X(get_physical_name, gmshModelGetPhysicalName)                           \
  X(get_nodes_for_physical_group, gmshModelMeshGetNodesForPhysicalGroup)   \
  X(get_entities_for_physical_group, gmshModelGetEntitiesForPhysicalGroup) \
  X(last_error, gmshLoggerGetLastError)

struct GmshSdk {
#define HTFETI_GMSH_MEMBER(member, name) decltype(&name) member = nullptr;
  HTFETI_GMSH_FUNCTIONS(HTFETI_GMSH_MEMBER)
#undef HTFETI_GMSH_MEMBER

  /// The SDK, loaded on the first call; std::invalid_argument if it cannot be loaded.
  static const GmshSdk& get() {
    static const GmshSdk sdk = load();  // (a failed load is retried on the next call)
    return sdk;
  }

  /// Throws std::runtime_error with the SDK's last message when a call reported an error.
  void check(int ierr) const {
    if (ierr == 0) return;
    char* text = nullptr;
    int e = 0;
    last_error(&text, &e);
    const std::string message = text && e == 0 ? text : "error " + std::to_string(ierr);
    free(text);
    throw std::runtime_error(message);
  }

 private:
  static GmshSdk load() {
    void* lib = dlopen(HTFETI_GMSH_LIBRARY, RTLD_LAZY | RTLD_LOCAL);
    if (!lib)
      throw std::invalid_argument(std::string("reading a .msh file needs the Gmsh SDK (") +
                                  HTFETI_GMSH_LIBRARY +
                                  "), which could not be loaded: " + dlerror());
    GmshSdk s;
    const auto find = [lib](auto& f, const char* name) {
      f = reinterpret_cast<std::remove_reference_t<decltype(f)>>(dlsym(lib, name));
      if (!f)
        throw std::invalid_argument(std::string("the Gmsh SDK (") + HTFETI_GMSH_LIBRARY +
                                    ") has no function " + name);
    };
#define HTFETI_GMSH_FIND(member, name) find(s.member, #name);
    HTFETI_GMSH_FUNCTIONS(HTFETI_GMSH_FIND)
#undef HTFETI_GMSH_FIND
    return s;
  }
};

// An array the SDK returned: copied into a vector, then freed.
template <class T>
std::vector<T> take(const GmshSdk& sdk, T* p, std::size_t n) {
  std::vector<T> v(p, p + n);
  sdk.free(p);
  return v;
}

// gmsh::model::mesh::getElements: element types, and per type the element tags and node tags.
void get_elements(const GmshSdk& sdk, std::vector<int>& types,
                  std::vector<std::vector<std::size_t>>& tags,
                  std::vector<std::vector<std::size_t>>& nodes, int dim, int tag) {
  int* t = nullptr;
  std::size_t nt = 0, ntags = 0, nnodes = 0;
  std::size_t **et = nullptr, **en = nullptr, *et_n = nullptr, *en_n = nullptr;
  int ierr = 0;
  sdk.get_elements(&t, &nt, &et, &et_n, &ntags, &en, &en_n, &nnodes, dim, tag, &ierr);
  sdk.check(ierr);
  types = take(sdk, t, nt);
  tags.assign(ntags, {});
  nodes.assign(nnodes, {});
  for (std::size_t i = 0; i < ntags; ++i) tags[i] = take(sdk, et[i], et_n[i]);
  for (std::size_t i = 0; i < nnodes; ++i) nodes[i] = take(sdk, en[i], en_n[i]);
  sdk.free(et), sdk.free(et_n), sdk.free(en), sdk.free(en_n);
}

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
  const GmshSdk& sdk = GmshSdk::get();
  for (int d = 3; d >= 2 && dim < 0; --d) {
    get_elements(sdk, types, tags, nodes, d, -1);
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
  const GmshSdk& sdk = GmshSdk::get();
  std::size_t *tag_p = nullptr, n_tags = 0, n_coord = 0, n_param = 0;
  double *coord_p = nullptr, *param_p = nullptr;
  int ierr = 0;
  sdk.get_nodes(&tag_p, &n_tags, &coord_p, &n_coord, &param_p, &n_param, -1, -1, 0, 0, &ierr);
  sdk.check(ierr);
  const std::vector<std::size_t> node_tags = take(sdk, tag_p, n_tags);
  const std::vector<double> coord = take(sdk, coord_p, n_coord);
  sdk.free(param_p);
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
  get_elements(GmshSdk::get(), et, etags, enodes, gd, entity);
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
  const GmshSdk& sdk = GmshSdk::get();
  int* dim_tags = nullptr;
  std::size_t n_dim_tags = 0;
  int ierr = 0;
  sdk.get_physical_groups(&dim_tags, &n_dim_tags, -1, &ierr);
  sdk.check(ierr);
  const std::vector<int> groups = take(sdk, dim_tags, n_dim_tags);  // (dim, tag) pairs
  for (std::size_t g = 0; g + 1 < groups.size(); g += 2) {
    const int gd = groups[g], gt = groups[g + 1];
    char* name_p = nullptr;
    sdk.get_physical_name(gd, gt, &name_p, &ierr);
    sdk.check(ierr);
    std::string name = name_p ? name_p : "";
    sdk.free(name_p);
    if (name.empty() && named_only) continue;
    if (name.empty()) name = std::to_string(gt);
    std::size_t *gnodes_p = nullptr, n_gnodes = 0, n_gcoord = 0;
    double* gcoord_p = nullptr;
    sdk.get_nodes_for_physical_group(gd, gt, &gnodes_p, &n_gnodes, &gcoord_p, &n_gcoord, &ierr);
    sdk.check(ierr);
    const std::vector<std::size_t> gnodes = take(sdk, gnodes_p, n_gnodes);
    sdk.free(gcoord_p);
    auto& ng = mesh.node_groups[name];
    for (std::size_t t : gnodes) {
      auto it = index.find(t);
      if (it != index.end()) ng.push_back(it->second);
    }
    std::sort(ng.begin(), ng.end());
    ng.erase(std::unique(ng.begin(), ng.end()), ng.end());
    int* ents_p = nullptr;
    std::size_t n_ents = 0;
    sdk.get_entities_for_physical_group(gd, gt, &ents_p, &n_ents, &ierr);
    sdk.check(ierr);
    const std::vector<int> ents = take(sdk, ents_p, n_ents);
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
  const GmshSdk& sdk = GmshSdk::get();
  Mesh mesh;
  mesh.partitions = partition_count(path);
  // Initializing the SDK sets OpenMP's thread count to its own default (1): restore ours after.
  const int threads = omp_get_max_threads();
  int ierr = 0;
  sdk.initialize(0, nullptr, 1, &ierr);
  if (ierr != 0) {
    omp_set_num_threads(threads);
    throw std::invalid_argument("mesh file '" + path + "': the Gmsh SDK did not start");
  }
  struct Finalize {
    const GmshSdk& sdk;
    int threads;
    ~Finalize() {
      int e = 0;
      sdk.finalize(&e);
      omp_set_num_threads(threads);
    }
  } finalize{sdk, threads};
  try {
    sdk.set_number("General.Terminal", 0, &ierr);
    sdk.check(ierr);
    sdk.set_number("General.Verbosity", 0, &ierr);
    sdk.check(ierr);
    sdk.open(path.c_str(), &ierr);
    sdk.check(ierr);
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
