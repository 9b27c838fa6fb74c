// A mesh that Gmsh partitioned in advance, one file per part (mesh.parts = "name.msh": the files
// name_1.msh ... name_N.msh that `gmsh mesh.msh -part N -setnumber Mesh.PartitionSplitMeshFiles 1
// -o name.msh` writes). Part k is subdomain k - 1 (TFETI), or the subdomains are renumbered
// cluster-major after the clusters are formed (H-TFETI-DP). Every rank reads only the part files
// of its own clusters; what a subdomain needs from the others comes by rendezvous, without any
// rank holding the whole mesh or the whole node list:
//
//   1. global node ids: the Gmsh node tags numbered densely in tag order (number_keys), so the
//      ids are those read_gmsh gives the whole mesh;
//   2. the domain boundary: the facets of each part that no other of its cells shares go to a
//      "home" rank by their smallest node id; a facet that arrives from one part only lies on the
//      boundary of the whole domain;
//   3. the copies of each node: every part sends each of its nodes (id, part, coordinates,
//      boundary flag, named groups) to the node's home rank (id * P / nodes), which lists the
//      parts that hold it, checks that they agree on the coordinates, merges the flags and the
//      groups (a node belongs to a group in every subdomain that holds it, as when the whole mesh
//      is split) and answers each part.
//   4. H-TFETI-DP only: the home ranks count the nodes each pair of parts shares; the counts
//      (about 14 neighbours per part) are gathered on every rank, which forms the clusters with
//      METIS (cluster_subdomains, as a whole mesh with cluster_split = "subdomains"); the parts
//      are then read again by the ranks that own their clusters and steps 1-3 repeated.
//
// Per rank: the part files of its clusters, their nodes' and boundary facets' records (a few
// dozen bytes each) in the rendezvous, the group names, and 3 counts per subdomain (the writers
// place every piece by them). Errors (a missing part file, a part count that does not match,
// nodes on which the parts disagree, a part hinged at a node) are agreed on by every rank.
#include <algorithm>
#include <climits>
#include <cstring>
#include <filesystem>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>

#include "htfeti/feti/input.hpp"
#include "htfeti/parallel/exchange.hpp"
#include "htfeti/parallel/key_numbering.hpp"
#include "mesh_source.hpp"

namespace htfeti {

namespace {

std::string part_path(const std::string& base, int k) {
  const std::filesystem::path b(base);
  return (b.parent_path() / (b.stem().string() + "_" + std::to_string(k) + b.extension().string()))
      .string();
}

long long bits_of(double x) {
  long long b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// Strings as one list of integers (length, then the characters) for the collectives.
void pack(const std::string& s, std::vector<long long>& out) {
  out.push_back(static_cast<long long>(s.size()));
  for (unsigned char ch : s) out.push_back(ch);
}
std::vector<std::string> unpack_all(const std::vector<std::vector<long long>>& lists) {
  std::vector<std::string> out;
  for (const auto& l : lists)
    for (size_t i = 0; i < l.size();) {
      const auto n = static_cast<size_t>(l[i++]);
      std::string s;
      for (size_t j = 0; j < n; ++j) s.push_back(static_cast<char>(l[i + j]));
      i += n;
      out.push_back(std::move(s));
    }
  return out;
}

// The sorted node numbers of facet j of cell e (unused entries -1).
std::array<int, 4> facet_key(const Mesh& m, int e, int j) {
  int local[4];
  const int n = std::min(cell_facet(m.type, j, local), 4), nc = cell_nodes(m.type);
  std::array<int, 4> k{-1, -1, -1, -1};
  for (int i = 0; i < n; ++i) {  // insertion sort of at most 4 entries
    int v = m.cells[static_cast<size_t>(e) * nc + local[i]], at = i;
    for (; at > 0 && k[at - 1] > v; --at) k[at] = k[at - 1];
    k[at] = v;
  }
  return k;
}

// A part whose cells form pieces joined only through a node (2D) or an edge (3D) is a mechanism
// that the rigid body motions of its pieces do not describe (partition.cpp, split_defects).
// Returns the number of facet-connected pieces and of node-connected ones.
std::pair<int, int> piece_counts(const Mesh& m) {
  const int ne = m.num_cells(), nc = cell_nodes(m.type), nf = cell_facet_count(m.type);
  std::vector<int> parent(ne);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  auto join = [&](int a, int b) {
    const int ra = root(a), rb = root(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  auto count = [&]() {
    int n = 0;
    for (int e = 0; e < ne; ++e) n += root(e) == e;
    return n;
  };
  std::vector<std::pair<std::array<int, 4>, int>> facets;
  for (int e = 0; e < ne; ++e)
    for (int j = 0; j < nf; ++j) facets.push_back({facet_key(m, e, j), e});
  std::sort(facets.begin(), facets.end());
  for (size_t i = 1; i < facets.size(); ++i)
    if (facets[i].first == facets[i - 1].first) join(facets[i].second, facets[i - 1].second);
  const int by_facet = count();
  const std::vector<int> comp = node_components(m.cells, nc, m.num_nodes());
  std::vector<int> first_cell(m.num_nodes(), -1);
  for (int e = 0; e < ne; ++e) {
    const int r = comp[m.cells[static_cast<size_t>(e) * nc]];
    if (first_cell[r] < 0) first_cell[r] = e;
  }
  int by_node = 0;
  for (int k = 0; k < m.num_nodes(); ++k) by_node += first_cell[k] >= 0;
  return {by_facet, by_node};
}

class PartitionedSource final : public HeldSubdomains {
 public:
  PartitionedSource(const ProblemSpec& spec, const Comm& comm)
      : HeldSubdomains(comm), base_(spec.mesh_parts), cluster_size_(spec.cluster_size) {
    count_parts(spec);
    const int P = comm_.size();
    if (cluster_size_ == 1) {
      subdomain_of_part_.resize(parts_);
      std::iota(subdomain_of_part_.begin(), subdomain_of_part_.end(), 0);
      cluster_first_.resize(parts_ + 1);
      std::iota(cluster_first_.begin(), cluster_first_.end(), 0);
      build(owned_parts());
    } else {
      // Provisional: parts in blocks by rank, for the adjacency that forms the clusters.
      std::vector<int> block;
      for (long long k = parts_ * static_cast<long long>(comm_.rank()) / P;
           k < parts_ * static_cast<long long>(comm_.rank() + 1) / P; ++k)
        block.push_back(static_cast<int>(k));
      subdomain_of_part_.resize(parts_);
      std::iota(subdomain_of_part_.begin(), subdomain_of_part_.end(), 0);
      build(block);
      form_clusters();
      build(owned_parts());
    }
    finish();
  }

  int dim() const override { return dim_; }
  int num_subdomains() const override { return parts_; }
  int num_clusters() const override { return static_cast<int>(cluster_first_.size()) - 1; }
  int cluster_first(int c) const override { return cluster_first_[c]; }
  long long num_nodes() const override { return nodes_; }
  long long subdomain_nodes() const override { return subdomain_nodes_; }
  void describe(const ProblemSpec&, nlohmann::json& j) const override {
    j["mesh"] = {{"parts", base_},
                 {"files", part_path(base_, 1) + " ... " + part_path(base_, parts_)},
                 {"element", to_string(type_)},
                 {"nodes", nodes_},
                 {"cells", cells_}};
    j["partitioner"] = "gmsh parts";
    if (bodies_ > 0) j["bodies"] = bodies_;  // counted where contact between bodies needs them
  }
  bool contact_surfaces(const ProblemSpec& spec, const Physics& physics,
                        ContactSurfaces& out) const override;

 private:
  // The number of parts: from part 1 (read by rank 0, which holds it first in every layout),
  // checked against decomposition.subdomains.
  void count_parts(const ProblemSpec& spec) {
    long long n = 0;
    agreed(comm_, [&] {
      if (comm_.rank() != 0) return;
      Mesh m = read_part(1);
      n = m.partitions;
      if (n < 1)
        throw std::invalid_argument("mesh.parts: '" + part_path(base_, 1) +
                                    "' is not one part of a partitioned mesh (no "
                                    "$PartitionedEntities): partition it with gmsh -part N and "
                                    "Mesh.PartitionSplitMeshFiles = 1, or give it as mesh.file");
      read_[0] = std::move(m);
    });
    MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm_.raw());
    parts_ = static_cast<int>(n);
    agreed(comm_, [&] {
      if (!spec.subdomains.empty() && (spec.subdomains.size() != 1 || spec.subdomains[0] != n))
        throw std::invalid_argument("decomposition.subdomains does not match the " +
                                    std::to_string(n) + " parts of the partitioned mesh '" + base_ +
                                    "' (each part is a subdomain: leave it out, or give " +
                                    std::to_string(n) + ")");
      if (cluster_size_ > parts_)
        throw std::invalid_argument(
            "decomposition.cluster_size = " + std::to_string(cluster_size_) + " exceeds the " +
            std::to_string(n) + " parts of '" + base_ + "'");
    });
  }

  Mesh read_part(int k) const {
    const std::string path = part_path(base_, k);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
      throw std::invalid_argument("mesh.parts: part " + std::to_string(k) + " of '" + base_ +
                                  "' is missing: no file '" + path + "'");
    GmshReadOptions o;
    o.named_groups_only = true;
    return read_gmsh(path, o);
  }

  // The parts of this rank's clusters (FetiLayout::cluster_range, as DualProblem assigns them).
  std::vector<int> owned_parts() const {
    FetiLayout L;
    L.num_clusters = num_clusters();
    const auto [c0, c1] = L.cluster_range(comm_.rank(), comm_.size());
    std::vector<int> part_of(parts_);
    for (int k = 0; k < parts_; ++k) part_of[subdomain_of_part_[k]] = k;
    std::vector<int> out;
    for (int s = cluster_first_[c0]; s < cluster_first_[c1]; ++s) out.push_back(part_of[s]);
    std::sort(out.begin(), out.end());
    return out;
  }

  // Reads `parts` (0-based) where not read yet, checks them, numbers the nodes and computes each
  // node's copies, boundary flag and groups (steps 1-3 above).
  void build(const std::vector<int>& parts) {
    read_parts(parts);
    gather_group_names();
    const auto gid = number_nodes();
    auto boundary = domain_boundary(gid);
    node_copies(gid, boundary);
  }

  // The part files, checked, and one cell type everywhere (agreed on by every rank).
  void read_parts(const std::vector<int>& parts) {
    agreed(comm_, [&] {
      std::map<int, Mesh> keep;
      for (int k : parts) {
        auto it = read_.find(k);
        Mesh m = it != read_.end() ? std::move(it->second) : read_part(k + 1);
        const std::string path = part_path(base_, k + 1);
        if (m.partitions != parts_)
          throw std::invalid_argument(
              "mesh.parts: '" + path + "' belongs to a mesh of " + std::to_string(m.partitions) +
              " parts, '" + part_path(base_, 1) + "' to one of " + std::to_string(parts_));
        check_cells(m, path);
        const auto [by_facet, by_node] = piece_counts(m);
        if (by_node < by_facet)
          throw std::invalid_argument(
              "mesh.parts: part " + std::to_string(k + 1) + " ('" + path +
              "') has pieces joined only through a node or an edge (a mechanism): partition the "
              "mesh again, e.g. with another number of parts");
        keep[k] = std::move(m);
      }
      read_ = std::move(keep);
    });
    // One element type and dimension everywhere (ranks that read nothing do not vote).
    {
      long long lo[2] = {LLONG_MAX, LLONG_MAX}, hi[2] = {-1, -1};
      for (const auto& [k, m] : read_) {
        const long long v[2] = {m.dim, static_cast<long long>(m.type)};
        for (int i = 0; i < 2; ++i) lo[i] = std::min(lo[i], v[i]), hi[i] = std::max(hi[i], v[i]);
      }
      MPI_Allreduce(MPI_IN_PLACE, lo, 2, MPI_LONG_LONG, MPI_MIN, comm_.raw());
      MPI_Allreduce(MPI_IN_PLACE, hi, 2, MPI_LONG_LONG, MPI_MAX, comm_.raw());
      agreed(comm_, [&] {
        if (lo[0] != hi[0] || lo[1] != hi[1])
          throw std::invalid_argument("mesh.parts: the parts of '" + base_ +
                                      "' do not all have the same cell type");
      });
      dim_ = static_cast<int>(hi[0]);
      type_ = static_cast<CellType>(hi[1]);
    }
  }

  // Step 1: every held node's global id (the node tags numbered densely in tag order), per part.
  std::map<int, std::vector<long long>> number_nodes() {
    std::vector<NumberingKey> keys;
    long long max_tag = 0;
    for (const auto& [k, m] : read_)
      for (std::size_t t : m.node_tags) {
        keys.push_back({static_cast<long long>(t), 0, 0, 0, 0, 0});
        max_tag = std::max(max_tag, static_cast<long long>(t));
      }
    MPI_Allreduce(MPI_IN_PLACE, &max_tag, 1, MPI_LONG_LONG, MPI_MAX, comm_.raw());
    const std::vector<long long> ids = number_keys(
        comm_, keys, max_tag + 1, [](const NumberingKey& k) { return k[0]; }, nodes_);
    std::map<int, std::vector<long long>> gid;
    {
      size_t i = 0;
      for (const auto& [k, m] : read_) {
        auto& g = gid[k];
        g.assign(ids.begin() + i, ids.begin() + i + m.node_tags.size());
        i += m.node_tags.size();
      }
    }
    return gid;
  }

  // The rank a node's records go to, by its global id (ids in increasing order over the ranks).
  int home(long long id) const {
    return static_cast<int>(static_cast<__int128>(id) * comm_.size() / std::max(nodes_, 1LL));
  }

  // Step 2: per part, its nodes on the boundary of the whole domain. A part's local nodes are in
  // tag order, the order of the global ids, so a facet's smallest local node is its smallest
  // global one: both parts of an interface facet send it to the same home rank.
  std::map<int, std::vector<char>> domain_boundary(
      const std::map<int, std::vector<long long>>& gid) {
    const int P = comm_.size();
    std::map<int, std::vector<char>> boundary;
    {
      std::vector<std::vector<long long>> send(P);
      std::vector<std::vector<std::pair<int, std::array<int, 4>>>> sent(P);  // (part, local facet)
      for (const auto& [k, m] : read_) {
        boundary[k].assign(m.num_nodes(), 0);
        const int nf = cell_facet_count(m.type);
        std::vector<std::array<int, 4>> f;
        for (int e = 0; e < m.num_cells(); ++e)
          for (int j = 0; j < nf; ++j) f.push_back(facet_key(m, e, j));
        std::sort(f.begin(), f.end());
        const auto& g = gid.at(k);
        for (size_t i = 0; i < f.size();) {
          size_t j = i;
          while (j < f.size() && f[j] == f[i]) ++j;
          if (j - i == 1) {
            const int r = home(g[f[i][0]]);
            for (int v : f[i]) send[r].push_back(v < 0 ? -1 : g[v]);
            sent[r].push_back({k, f[i]});
          }
          i = j;
        }
      }
      const auto recv = exchange_lists(comm_, send);
      std::map<std::array<long long, 4>, int> count;
      for (const auto& l : recv)
        for (size_t i = 0; i < l.size(); i += 4)
          ++count[std::array<long long, 4>{l[i], l[i + 1], l[i + 2], l[i + 3]}];
      std::vector<std::vector<long long>> answer(P);
      for (int r = 0; r < P; ++r)
        for (size_t i = 0; i < recv[r].size(); i += 4)
          answer[r].push_back(count[std::array<long long, 4>{recv[r][i], recv[r][i + 1],
                                                             recv[r][i + 2], recv[r][i + 3]}] == 1);
      const auto flags = exchange_lists(comm_, answer);
      for (int r = 0; r < P; ++r)
        for (size_t i = 0; i < sent[r].size(); ++i)
          if (flags[r][i])
            for (int v : sent[r][i].second)
              if (v >= 0) boundary[sent[r][i].first][v] = 1;
    }
    return boundary;
  }

  // Step 3: the copies, coordinates (checked), boundary flags and groups of every node, merged at
  // its home rank; then each held part's SubdomainMesh.
  void node_copies(const std::map<int, std::vector<long long>>& gid,
                   std::map<int, std::vector<char>>& boundary) {
    const int P = comm_.size();
    const int G = static_cast<int>(node_names_.size() + 63) / 64;
    const int W = 7 + G;  // id, tag, part, x, y, z, boundary, group words
    std::vector<std::vector<long long>> send(P);
    std::vector<std::vector<std::pair<int, int>>> sent(P);  // (part, local node)
    for (const auto& [k, m] : read_) {
      std::vector<std::vector<long long>> words(m.num_nodes(), std::vector<long long>(G, 0));
      for (const auto& [name, nodes] : m.node_groups) {
        const auto at = std::lower_bound(node_names_.begin(), node_names_.end(), name);
        const int bit = static_cast<int>(at - node_names_.begin());
        for (int v : nodes) words[v][bit / 64] |= 1LL << (bit % 64);
      }
      const auto& g = gid.at(k);
      for (int v = 0; v < m.num_nodes(); ++v) {
        const int r = home(g[v]);
        auto& out = send[r];
        out.insert(out.end(),
                   {g[v], static_cast<long long>(m.node_tags[v]), k, bits_of(m.coords[3 * v]),
                    bits_of(m.coords[3 * v + 1]), bits_of(m.coords[3 * v + 2]), boundary[k][v]});
        out.insert(out.end(), words[v].begin(), words[v].end());
        sent[r].push_back({k, v});
      }
    }
    const auto recv = exchange_lists(comm_, send);
    std::vector<std::vector<long long>> answer(P);
    agreed(comm_, [&] {
      std::vector<const long long*> all;
      for (const auto& l : recv)
        for (size_t i = 0; i < l.size(); i += W) all.push_back(&l[i]);
      std::sort(all.begin(), all.end(), [](const long long* a, const long long* b) {
        return a[0] != b[0] ? a[0] < b[0] : a[2] < b[2];
      });
      std::map<long long, std::vector<long long>> merged;  // id -> [n, parts..., boundary, words]
      for (size_t i = 0; i < all.size();) {
        size_t j = i;
        std::vector<long long> parts;
        long long flag = 0;
        std::vector<long long> words(G, 0);
        for (; j < all.size() && all[j][0] == all[i][0]; ++j) {
          const long long* a = all[j];
          if (a[3] != all[i][3] || a[4] != all[i][4] || a[5] != all[i][5]) {
            double x[3], y[3];
            std::memcpy(x, all[i] + 3, sizeof x), std::memcpy(y, a + 3, sizeof y);
            throw std::invalid_argument(
                "mesh.parts: node " + std::to_string(a[1]) + " lies at (" + std::to_string(x[0]) +
                ", " + std::to_string(x[1]) + ", " + std::to_string(x[2]) + ") in part " +
                std::to_string(all[i][2] + 1) + " and at (" + std::to_string(y[0]) + ", " +
                std::to_string(y[1]) + ", " + std::to_string(y[2]) + ") in part " +
                std::to_string(a[2] + 1) + ": the part files are not of one mesh");
          }
          if (!parts.empty() && parts.back() == a[2])
            throw std::invalid_argument("mesh.parts: part " + std::to_string(a[2] + 1) +
                                        " is read twice (node " + std::to_string(a[1]) + ")");
          parts.push_back(a[2]);
          flag |= a[6];
          for (int w = 0; w < G; ++w) words[w] |= a[7 + w];
        }
        auto& out = merged[all[i][0]];
        out.push_back(static_cast<long long>(parts.size()));
        out.insert(out.end(), parts.begin(), parts.end());
        out.push_back(flag);
        out.insert(out.end(), words.begin(), words.end());
        if (cluster_size_ > 1 && !formed_)
          for (size_t a = 0; a < parts.size(); ++a)
            for (size_t b = 0; b < parts.size(); ++b)
              if (a != b) ++shared_[{static_cast<int>(parts[a]), static_cast<int>(parts[b])}];
        i = j;
      }
      for (int r = 0; r < P; ++r)
        for (size_t i = 0; i < recv[r].size(); i += W) {
          const auto& m = merged[recv[r][i]];
          answer[r].insert(answer[r].end(), m.begin(), m.end());
        }
    });
    const auto back = exchange_lists(comm_, answer);
    meshes_.clear();
    for (const auto& [k, m] : read_)
      meshes_[subdomain_of_part_[k]] = subdomain_mesh(k, m, gid.at(k));
    for (int r = 0; r < P; ++r) {
      size_t i = 0;
      for (const auto& [k, v] : sent[r]) {
        SubdomainMesh& sm = meshes_[subdomain_of_part_[k]];
        const auto n = static_cast<size_t>(back[r][i]);
        auto& copies = pending_copies_[subdomain_of_part_[k]][v];
        for (size_t c = 0; c < n; ++c)
          copies.push_back(subdomain_of_part_[static_cast<int>(back[r][i + 1 + c])]);
        sm.on_boundary[v] = static_cast<char>(back[r][i + 1 + n]);
        for (int b = 0; b < static_cast<int>(node_names_.size()); ++b)
          if (back[r][i + 2 + n + b / 64] >> (b % 64) & 1)
            sm.node_groups[node_names_[b]].push_back(v);
        i += 2 + n + G;
      }
    }
    for (auto& [s, sm] : meshes_) {
      auto& pc = pending_copies_[s];
      sm.copy_offset.assign(sm.num_nodes() + 1, 0);
      sm.copy_list.clear();
      for (int v = 0; v < sm.num_nodes(); ++v) {
        auto& c = pc[v];
        std::sort(c.begin(), c.end());
        sm.copy_list.insert(sm.copy_list.end(), c.begin(), c.end());
        sm.copy_offset[v + 1] = static_cast<int>(sm.copy_list.size());
      }
      for (auto& [name, nodes] : sm.node_groups) std::sort(nodes.begin(), nodes.end());
    }
    pending_copies_.clear();
  }

  // The SubdomainMesh of part k before its copies, boundary flags and node groups are known.
  SubdomainMesh subdomain_mesh(int k, const Mesh& m, const std::vector<long long>& gid) {
    SubdomainMesh sm;
    sm.id = subdomain_of_part_[k];
    sm.cluster =
        static_cast<int>(std::upper_bound(cluster_first_.begin(), cluster_first_.end(), sm.id) -
                         cluster_first_.begin() - 1);
    sm.dim = m.dim;
    sm.type = m.type;
    sm.coords = m.coords;
    sm.global_node = gid;
    sm.cells = m.cells;
    sm.on_boundary.assign(m.num_nodes(), 0);
    for (const auto& [name, fg] : m.facet_groups)
      if (!fg.nodes.empty()) sm.facet_groups[name] = {fg.facet_nodes, fg.nodes};
    for (const auto& [name, cg] : m.cell_groups)
      if (!cg.empty()) sm.cell_groups[name] = cg;
    pending_copies_[sm.id].assign(m.num_nodes(), {});
    return sm;
  }

  // The union of the group names over all parts (every rank the same sorted lists).
  void gather_group_names() {
    for (auto* names : {&node_names_, &facet_names_, &cell_names_}) {
      std::vector<long long> mine;
      for (const auto& [k, m] : read_) {
        if (names == &node_names_)
          for (const auto& [n, v] : m.node_groups) pack(n, mine);
        if (names == &facet_names_)
          for (const auto& [n, v] : m.facet_groups) pack(n, mine);
        if (names == &cell_names_)
          for (const auto& [n, v] : m.cell_groups) pack(n, mine);
      }
      std::vector<std::string> all = unpack_all(all_gather(comm_, mine));
      std::sort(all.begin(), all.end());
      all.erase(std::unique(all.begin(), all.end()), all.end());
      *names = std::move(all);
    }
  }

  // Step 4: clusters from the gathered counts of shared nodes; parts renumbered cluster-major.
  void form_clusters() {
    std::vector<long long> mine;
    for (const auto& [ab, w] : shared_) mine.insert(mine.end(), {ab.first, ab.second, w});
    shared_.clear();
    std::vector<std::map<int, int>> adj(parts_);
    for (const auto& l : all_gather(comm_, mine))
      for (size_t i = 0; i < l.size(); i += 3)
        adj[l[i]][static_cast<int>(l[i + 1])] += static_cast<int>(l[i + 2]);
    // Bodies: connected components of the part graph; parts ordered body-major.
    std::vector<int> body(parts_, -1), order;
    int nb = 0;
    std::vector<int> body_first{0};
    for (int k = 0; k < parts_; ++k) {
      if (body[k] >= 0) continue;
      std::vector<int> stack{k};
      body[k] = nb;
      std::vector<int> members;
      while (!stack.empty()) {
        const int a = stack.back();
        stack.pop_back();
        members.push_back(a);
        for (const auto& [b, w] : adj[a])
          if (body[b] < 0) body[b] = nb, stack.push_back(b);
      }
      std::sort(members.begin(), members.end());
      order.insert(order.end(), members.begin(), members.end());
      body_first.push_back(static_cast<int>(order.size()));
      ++nb;
    }
    std::vector<int> pos(parts_);
    for (int i = 0; i < parts_; ++i) pos[order[i]] = i;
    std::vector<std::map<int, int>> adj_ordered(parts_);
    for (int k = 0; k < parts_; ++k)
      for (const auto& [b, w] : adj[k]) adj_ordered[pos[k]][pos[b]] = w;
    const std::vector<int> cluster = cluster_subdomains(adj_ordered, body_first, cluster_size_);
    const ClusterOrder co = order_by_cluster(cluster);
    for (int k = 0; k < parts_; ++k) subdomain_of_part_[k] = co.new_id[pos[k]];
    cluster_first_ = co.cluster_first;
    formed_ = true;
  }

  // Counts per subdomain for the writers, and the totals.
  void finish() {
    std::vector<long long> mine;
    for (const auto& [s, m] : meshes_)
      mine.insert(mine.end(),
                  {s, m.num_nodes(), m.num_cells(), static_cast<long long>(m.cells.size())});
    counts_.assign(parts_, {});
    subdomain_nodes_ = 0, cells_ = 0;
    for (const auto& l : all_gather(comm_, mine))
      for (size_t i = 0; i < l.size(); i += 4) {
        counts_[l[i]] = {l[i + 1], l[i + 2], l[i + 3]};
        subdomain_nodes_ += l[i + 1], cells_ += l[i + 2];
      }
    read_.clear();
  }

  std::string where() const override { return "the partitioned mesh '" + base_ + "'"; }

  std::string base_;
  int cluster_size_ = 1, parts_ = 0, dim_ = 3;
  CellType type_ = CellType::tet4;
  bool formed_ = false;
  std::vector<int> subdomain_of_part_, cluster_first_;
  std::map<int, Mesh> read_;  // part (0-based) -> its mesh, while building
  std::map<int, std::vector<std::vector<int>>> pending_copies_;
  std::map<std::pair<int, int>, long long> shared_;
  long long nodes_ = 0, subdomain_nodes_ = 0, cells_ = 0;
  mutable int bodies_ = 0;  // set by contact_surfaces
};

// Contact between bodies (step 5, only for conditions with a master group): the surfaces
// gathered on every rank. The bodies are the connected pieces of the parts joined wherever
// they share a node (a part that Gmsh cut across two bodies has a piece in each); the facets of
// the contact groups are listed by every part that has them and kept once, in part order; the
// part holding the one cell a facet bounds gives its outward normal and body (a facet bounded
// by no cell or by two is refused, as on the whole mesh); and the parts holding a surface node
// give its coordinates, copies and Dirichlet components. Per rank: the surfaces (a few records
// per facet and node), the pieces' summary and the interface nodes' records in the rendezvous.
bool PartitionedSource::contact_surfaces(const ProblemSpec& spec, const Physics& physics,
                                         ContactSurfaces& out) const {
  const int P = comm_.size(), dpn = physics.dofs_per_node();
  out = ContactSurfaces{};
  out.dim = dim_;
  std::vector<std::string> names;
  for (const auto& c : spec.contact)
    if (!c.master.empty()) names.insert(names.end(), {c.group, c.master});
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  std::vector<int> part_of(parts_);
  for (int k = 0; k < parts_; ++k) part_of[subdomain_of_part_[k]] = k;
  const int nc = cell_nodes(type_);

  // Pieces of the held parts (connected through cells), numbered in each part by first node.
  std::map<int, std::vector<int>> piece_of_node;  // subdomain -> local node -> piece
  std::vector<long long> mine;                    // (part, pieces)
  for (const auto& [sd, sm] : meshes_) {
    const std::vector<int> comp = node_components(sm.cells, nc, sm.num_nodes());
    std::vector<int> piece(sm.num_nodes()), of_root(sm.num_nodes(), -1);
    int n = 0;
    for (int k = 0; k < sm.num_nodes(); ++k) {
      if (of_root[comp[k]] < 0) of_root[comp[k]] = n++;
      piece[k] = of_root[comp[k]];
    }
    piece_of_node[sd] = std::move(piece);
    mine.insert(mine.end(), {part_of[sd], n});
  }
  std::vector<long long> first_piece(parts_ + 1, 0);
  for (const auto& l : all_gather(comm_, mine))
    for (size_t i = 0; i < l.size(); i += 2) first_piece[l[i] + 1] = l[i + 1];
  for (int k = 0; k < parts_; ++k) first_piece[k + 1] += first_piece[k];
  const long long pieces = first_piece[parts_];
  auto global_piece = [&](int sd, int k) {
    return first_piece[part_of[sd]] + piece_of_node[sd][k];
  };

  // Bodies: pieces joined through the interface nodes (at the nodes' home ranks), numbered by
  // their lowest global node, as the whole mesh's bodies are by their first cell.
  std::vector<long long> lowest(pieces, LLONG_MAX);
  {
    std::vector<std::vector<long long>> send(P);
    std::vector<long long> low;
    for (const auto& [sd, sm] : meshes_)
      for (int k = 0; k < sm.num_nodes(); ++k) {
        const long long gp = global_piece(sd, k);
        low.insert(low.end(), {gp, sm.global_node[k]});
        if (sm.num_copies(k) > 1)
          send[home(sm.global_node[k])].insert(send[home(sm.global_node[k])].end(),
                                               {sm.global_node[k], gp});
      }
    std::vector<long long> local_low;
    {
      std::map<long long, long long> m;
      for (size_t i = 0; i < low.size(); i += 2) {
        auto it = m.find(low[i]);
        if (it == m.end() || low[i + 1] < it->second) m[low[i]] = low[i + 1];
      }
      for (const auto& [gp, g] : m) local_low.insert(local_low.end(), {gp, g});
    }
    for (const auto& l : all_gather(comm_, local_low))
      for (size_t i = 0; i < l.size(); i += 2) lowest[l[i]] = std::min(lowest[l[i]], l[i + 1]);
    std::vector<std::pair<long long, long long>> at;
    for (const auto& l : exchange_lists(comm_, send))
      for (size_t i = 0; i < l.size(); i += 2) at.push_back({l[i], l[i + 1]});
    std::sort(at.begin(), at.end());
    std::vector<long long> edges;
    for (size_t i = 0; i < at.size();) {
      size_t j = i + 1;
      for (; j < at.size() && at[j].first == at[i].first; ++j)
        if (at[j].second != at[i].second) edges.insert(edges.end(), {at[i].second, at[j].second});
      i = j;
    }
    std::vector<long long> parent(pieces);
    std::iota(parent.begin(), parent.end(), 0LL);
    auto root = [&](long long a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    for (const auto& l : all_gather(comm_, edges))
      for (size_t i = 0; i < l.size(); i += 2) {
        const long long a = root(l[i]), b = root(l[i + 1]);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    std::map<long long, long long> body_low;  // root -> lowest node of the body
    for (long long p = 0; p < pieces; ++p) {
      auto it = body_low.find(root(p));
      if (it == body_low.end() || lowest[p] < it->second) body_low[root(p)] = lowest[p];
    }
    std::vector<std::pair<long long, long long>> by_low;
    for (const auto& [r, g] : body_low) by_low.push_back({g, r});
    std::sort(by_low.begin(), by_low.end());
    std::map<long long, int> body_of_root;
    for (size_t b = 0; b < by_low.size(); ++b) body_of_root[by_low[b].second] = static_cast<int>(b);
    for (long long p = 0; p < pieces; ++p) lowest[p] = body_of_root[root(p)];  // now: the body
    out.num_bodies = bodies_ = static_cast<int>(by_low.size());
  }
  const std::vector<long long>& body_of_piece = lowest;

  // The facets of the contact groups, from every part that lists them, kept once (the first in
  // part order, then in the part's order).
  std::vector<int> facet_nodes(names.size(), 0);
  std::vector<std::vector<long long>> facets(names.size());  // global nodes, cyclic
  {
    std::vector<long long> list;  // part, group, fn, nodes...
    for (const auto& [sd, sm] : meshes_)
      for (size_t g = 0; g < names.size(); ++g) {
        auto it = sm.facet_groups.find(names[g]);
        if (it == sm.facet_groups.end()) continue;
        const int fn = it->second.facet_nodes;
        for (size_t f = 0; f < it->second.nodes.size(); f += fn) {
          list.insert(list.end(), {part_of[sd], static_cast<long long>(g), fn});
          for (int b = 0; b < fn; ++b) list.push_back(sm.global_node[it->second.nodes[f + b]]);
        }
      }
    std::vector<std::vector<long long>> all;  // by part
    std::vector<std::pair<long long, std::vector<long long>>> records;
    for (const auto& l : all_gather(comm_, list))
      for (size_t i = 0; i < l.size();) {
        const int fn = static_cast<int>(l[i + 2]);
        records.push_back(
            {l[i], std::vector<long long>(l.begin() + i + 1, l.begin() + i + 3 + fn)});
        i += 3 + fn;
      }
    std::stable_sort(records.begin(), records.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::set<std::vector<long long>> seen;
    for (const auto& [part, r] : records) {
      const int g = static_cast<int>(r[0]), fn = static_cast<int>(r[1]);
      std::vector<long long> key(r.begin() + 2, r.end());
      std::sort(key.begin(), key.end());
      key.push_back(g);
      if (!seen.insert(key).second) continue;
      facet_nodes[g] = fn;
      facets[g].insert(facets[g].end(), r.begin() + 2, r.end());
    }
  }

  // The surface nodes: the facets' nodes in global order.
  std::vector<long long>& nodes = out.global;
  for (const auto& f : facets) nodes.insert(nodes.end(), f.begin(), f.end());
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  const int ns = static_cast<int>(nodes.size());
  auto index = [&](long long g) {
    return static_cast<int>(std::lower_bound(nodes.begin(), nodes.end(), g) - nodes.begin());
  };
  long long nf_total = 0;
  std::vector<long long> facet_first(names.size() + 1, 0);
  for (size_t g = 0; g < names.size(); ++g)
    facet_first[g + 1] = facet_first[g] + (facet_nodes[g] ? facets[g].size() / facet_nodes[g] : 0);
  nf_total = facet_first[names.size()];

  // Per facet: the cells that hold it, the normal and body from the part holding the one cell;
  // per surface node: the holder of lowest rank gives the coordinates.
  std::vector<long long> cells_at(nf_total, 0), body(nf_total, -1);
  std::vector<double> normal(3 * static_cast<size_t>(nf_total), 0.0), coords(3 * ns, 0.0);
  std::vector<int> holder(ns, P);
  std::vector<long long> copies(ns, 0), owner(ns, LLONG_MAX), fixed(ns, 0);
  for (const auto& [sd, sm] : meshes_) {
    std::vector<int> local(ns, -1);
    for (int k = 0; k < sm.num_nodes(); ++k) {
      const int i = index(sm.global_node[k]);
      if (i < ns && nodes[i] == sm.global_node[k]) local[i] = k;
    }
    const std::vector<unsigned char> fx =
        fixed_components(spec, dpn, sm.node_groups, sm.num_nodes());
    for (int i = 0; i < ns; ++i) {
      const int k = local[i];
      if (k < 0) continue;
      holder[i] = std::min(holder[i], comm_.rank());
      copies[i] = sm.num_copies(k);
      owner[i] = std::min<long long>(owner[i], sm.copies(k)[0]);
      fixed[i] |= fx[k];
    }
    std::vector<int> first(sm.num_nodes() + 1, 0), list(sm.cells.size());
    for (int v : sm.cells) ++first[v + 1];
    for (int k = 0; k < sm.num_nodes(); ++k) first[k + 1] += first[k];
    {
      std::vector<int> at(first.begin(), first.end() - 1);
      for (int e = 0; e < sm.num_cells(); ++e)
        for (int a = 0; a < nc; ++a) list[at[sm.cells[static_cast<size_t>(e) * nc + a]]++] = e;
    }
    for (size_t g = 0; g < names.size(); ++g) {
      const int fn = facet_nodes[g];
      for (long long f = 0; fn > 0 && f < facet_first[g + 1] - facet_first[g]; ++f) {
        int v[4];
        bool held = true;
        for (int b = 0; b < fn && held; ++b) {
          v[b] = local[index(facets[g][f * fn + b])];
          held = v[b] >= 0;
        }
        if (!held) continue;
        for (int c = first[v[0]]; c < first[v[0] + 1]; ++c) {
          const int* cell = sm.cells.data() + static_cast<size_t>(list[c]) * nc;
          if (!cell_holds_facet(cell, nc, v, fn)) continue;
          const long long id = facet_first[g] + f;
          ++cells_at[id];
          const auto n = outward_normal(dim_, sm.coords.data(), v, fn, cell, nc);
          for (int d = 0; d < 3; ++d) normal[3 * id + d] = n[d];
          body[id] = body_of_piece[global_piece(sd, cell[0])];
        }
      }
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, holder.data(), ns, MPI_INT, MPI_MIN, comm_.raw());
  for (const auto& [sd, sm] : meshes_)
    for (int k = 0; k < sm.num_nodes(); ++k) {
      const int i = index(sm.global_node[k]);
      if (i < ns && nodes[i] == sm.global_node[k] && holder[i] == comm_.rank())
        for (int d = 0; d < 3; ++d) coords[3 * i + d] = sm.coords[3 * static_cast<size_t>(k) + d];
    }
  const MPI_Comm c = comm_.raw();
  MPI_Allreduce(MPI_IN_PLACE, coords.data(), 3 * ns, MPI_DOUBLE, MPI_SUM, c);
  MPI_Allreduce(MPI_IN_PLACE, copies.data(), ns, MPI_LONG_LONG, MPI_MAX, c);
  MPI_Allreduce(MPI_IN_PLACE, owner.data(), ns, MPI_LONG_LONG, MPI_MIN, c);
  MPI_Allreduce(MPI_IN_PLACE, fixed.data(), ns, MPI_LONG_LONG, MPI_BOR, c);
  MPI_Allreduce(MPI_IN_PLACE, cells_at.data(), static_cast<int>(nf_total), MPI_LONG_LONG, MPI_SUM,
                c);
  MPI_Allreduce(MPI_IN_PLACE, normal.data(), static_cast<int>(3 * nf_total), MPI_DOUBLE, MPI_SUM,
                c);
  MPI_Allreduce(MPI_IN_PLACE, body.data(), static_cast<int>(nf_total), MPI_LONG_LONG, MPI_MAX, c);

  out.coords = std::move(coords);
  out.copies.assign(copies.begin(), copies.end());
  out.owner.assign(owner.begin(), owner.end());
  out.fixed.assign(fixed.begin(), fixed.end());
  for (size_t g = 0; g < names.size(); ++g) {
    ContactSurfaces::Group& grp = out.groups[names[g]];
    const int fn = facet_nodes[g];
    if (fn == 0) {
      grp.error = no_facets_error(names[g], dim_);
      continue;
    }
    ContactSurface& s = grp.surface;
    s.facet_nodes = fn;
    std::set<int> bodies;
    for (long long f = 0; f < facet_first[g + 1] - facet_first[g]; ++f) {
      const long long id = facet_first[g] + f;
      if (cells_at[id] != 1) {
        grp.error = not_boundary_error(names[g], facets[g][f * fn] + 1, facets[g][f * fn + 1] + 1);
        break;
      }
      for (int b = 0; b < fn; ++b) s.nodes.push_back(index(facets[g][f * fn + b]));
      s.normals.push_back({normal[3 * id], normal[3 * id + 1], normal[3 * id + 2]});
      bodies.insert(static_cast<int>(body[id]));
    }
    grp.bodies.assign(bodies.begin(), bodies.end());
  }
  return true;
}

}  // namespace

std::unique_ptr<MeshSource> make_partitioned_source(const ProblemSpec& spec, const Comm& comm) {
  return std::make_unique<PartitionedSource>(spec, comm);
}

}  // namespace htfeti
