#include "htfeti/partition/partition.hpp"

#include <metis.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <new>
#include <numeric>
#include <stdexcept>
#include <string>

#include "htfeti/fem/element.hpp"

namespace htfeti {

namespace {

using FacetKey = std::array<int, 4>;

FacetKey facet_key(const int* nodes, int n) {
  FacetKey k{-1, -1, -1, -1};
  n = std::min(n, 4);
  for (int i = 0; i < n; ++i) {  // insertion sort of at most 4 entries
    int v = nodes[i], j = i;
    for (; j > 0 && k[j - 1] > v; --j) k[j] = k[j - 1];
    k[j] = v;
  }
  return k;
}

void metis_check(int status, const char* what) {
  if (status == METIS_ERROR_MEMORY) throw std::bad_alloc();  // "out of memory", exit 2
  if (status != METIS_OK)
    throw std::runtime_error(std::string("METIS failed while partitioning the ") + what);
}

// Boundary facets: (sorted key, cell) of every facet of every cell; a key met once is on the
// boundary. Sorted by key.
std::vector<std::pair<FacetKey, int>> all_facets(const Mesh& mesh) {
  std::vector<std::pair<FacetKey, int>> f;
  const int nc = cell_nodes(mesh.type), nf = cell_facet_count(mesh.type);
  f.reserve(static_cast<size_t>(mesh.num_cells()) * nf);
  int local[4], glob[4];
  for (int e = 0; e < mesh.num_cells(); ++e)
    for (int j = 0; j < nf; ++j) {
      const int n = cell_facet(mesh.type, j, local);
      for (int i = 0; i < n; ++i) glob[i] = mesh.cells[static_cast<size_t>(e) * nc + local[i]];
      f.push_back({facet_key(glob, n), e});
    }
  std::sort(f.begin(), f.end());
  return f;
}

// The measure of a facet given by its nodes in cyclic order: a length (2 nodes), a triangle's
// area (3) or a planar quadrilateral's, half the norm of its diagonals' cross product (4).
double facet_measure(const Mesh& mesh, const int* nodes, int n) {
  auto x = [&](int a, int c) { return mesh.coords[3 * static_cast<size_t>(nodes[a]) + c]; };
  if (n == 2) return std::hypot(x(1, 0) - x(0, 0), x(1, 1) - x(0, 1), x(1, 2) - x(0, 2));
  const int p = n == 3 ? 0 : 1, q = n == 3 ? 0 : 3;  // diagonals (2-0, 3-1), or sides (1-0, 2-0)
  double u[3], v[3];
  for (int c = 0; c < 3; ++c)
    u[c] = x(n == 3 ? 1 : 2, c) - x(0, c), v[c] = x(n == 3 ? 2 : q, c) - x(p, c);
  return 0.5 * std::hypot(u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                          u[0] * v[1] - u[1] * v[0]);
}

// The facet measures of cell e (its cell_facet_count(type) facets).
int cell_facet_measures(const Mesh& mesh, int e, double* out) {
  const int nc = cell_nodes(mesh.type), nf = cell_facet_count(mesh.type);
  int local[4], glob[4];
  for (int j = 0; j < nf; ++j) {
    const int n = cell_facet(mesh.type, j, local);
    for (int i = 0; i < n; ++i) glob[i] = mesh.cells[static_cast<size_t>(e) * nc + local[i]];
    out[j] = facet_measure(mesh, glob, n);
  }
  return nf;
}

// METIS k-way with the edge-cut objective on the dual graph of the given cells (all cells when
// null), each edge weighted by the measure of the facet the two cells share: METIS then minimizes
// the area (3D) or length (2D) of the interfaces. Weights are integers, the largest facet
// 2^30 / (graph edges) but at most 10^6, the smallest at least 1 (METIS sums them in 32 bits).
void split_cells_by_area(const Mesh& mesh, const std::vector<int>* cells, idx_t nparts,
                         idx_t* options, idx_t* out) {
  const int ne = cells ? static_cast<int>(cells->size()) : mesh.num_cells();
  const int nc = cell_nodes(mesh.type), nf = cell_facet_count(mesh.type);
  std::vector<std::pair<FacetKey, int>> f;  // (key, local cell * nf + facet) of the subset
  f.reserve(static_cast<size_t>(ne) * nf);
  int lf[4], glob[4];
  for (int i = 0; i < ne; ++i)
    for (int j = 0; j < nf; ++j) {
      const int n = cell_facet(mesh.type, j, lf), e = cells ? (*cells)[i] : i;
      for (int a = 0; a < n; ++a) glob[a] = mesh.cells[static_cast<size_t>(e) * nc + lf[a]];
      f.push_back({facet_key(glob, n), i * nf + j});
    }
  std::sort(f.begin(), f.end());
  std::vector<std::array<int, 2>> pairs;  // (first facet, second facet) of each shared facet
  for (size_t k = 0; k + 1 < f.size(); ++k)
    if (f[k].first == f[k + 1].first) pairs.push_back({f[k].second, f[k + 1].second}), ++k;
  std::vector<double> measure(pairs.size());
  double largest = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const int i = pairs[k][0] / nf, e = cells ? (*cells)[i] : i;
    const int n = cell_facet(mesh.type, pairs[k][0] % nf, lf);
    for (int a = 0; a < n; ++a) glob[a] = mesh.cells[static_cast<size_t>(e) * nc + lf[a]];
    measure[k] = facet_measure(mesh, glob, n);
    largest = std::max(largest, measure[k]);
  }
  const double scale = std::min(
      1e6, std::max(1.0, std::floor(1073741824.0 / std::max<size_t>(1, 2 * pairs.size()))));
  std::vector<idx_t> xadj(ne + 1, 0), adjncy(2 * pairs.size()), adjwgt(2 * pairs.size());
  for (const auto& pr : pairs) ++xadj[pr[0] / nf + 1], ++xadj[pr[1] / nf + 1];
  for (int i = 0; i < ne; ++i) xadj[i + 1] += xadj[i];
  std::vector<idx_t> fill(xadj.begin(), xadj.end() - 1);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const idx_t w = std::max<idx_t>(
        1, static_cast<idx_t>(std::lround(largest > 0 ? scale * measure[k] / largest : 1)));
    const int a = pairs[k][0] / nf, b = pairs[k][1] / nf;
    adjncy[fill[a]] = b, adjwgt[fill[a]++] = w;
    adjncy[fill[b]] = a, adjwgt[fill[b]++] = w;
  }
  idx_t nv = ne, ncon = 1, objval = 0;
  options[METIS_OPTION_OBJTYPE] = METIS_OBJTYPE_CUT;
  metis_check(METIS_PartGraphKway(&nv, &ncon, xadj.data(), adjncy.data(), nullptr, nullptr,
                                  adjwgt.data(), &nparts, nullptr, nullptr, options, &objval, out),
              "mesh");
}

// Bodies: the connected components of the cells (cells sharing a node), numbered in the order
// of their first cell. Union-find over the nodes.
int find_bodies(const Mesh& mesh, std::vector<int>& cell_body) {
  const int ne = mesh.num_cells(), nn = mesh.num_nodes(), nc = cell_nodes(mesh.type);
  const std::vector<int> component = node_components(mesh.cells, nc, nn);
  std::vector<int> body_of_root(nn, -1);
  int bodies = 0;
  cell_body.resize(ne);
  for (int e = 0; e < ne; ++e) {
    const int r = component[mesh.cells[static_cast<size_t>(e) * nc]];
    if (body_of_root[r] < 0) body_of_root[r] = bodies++;
    cell_body[e] = body_of_root[r];
  }
  return bodies;
}

// METIS k-way on the dual graph of the given cells (all cells: the whole mesh as it is);
// part[e] in [0, nparts) for e in cells.
void split_cells(const Mesh& mesh, const std::vector<int>* cells, int nparts_in,
                 PartitionObjective objective, int seed, std::vector<idx_t>& part,
                 bool contiguous = false) {
  if (nparts_in <= 1) {
    if (cells)
      for (int e : *cells) part[e] = 0;
    return;
  }
  const int nc = cell_nodes(mesh.type);
  const int ne = cells ? static_cast<int>(cells->size()) : mesh.num_cells();
  std::vector<idx_t> eptr(ne + 1), eind;
  std::vector<int> local;  // global node -> local, for a subset of cells
  idx_t nn = mesh.num_nodes();
  if (!cells) {
    eind.assign(mesh.cells.begin(), mesh.cells.end());
  } else {
    local.assign(mesh.num_nodes(), -1);
    nn = 0;
    for (int e : *cells)
      for (int a = 0; a < nc; ++a) {
        const int g = mesh.cells[static_cast<size_t>(e) * nc + a];
        if (local[g] < 0) local[g] = static_cast<int>(nn++);
        eind.push_back(local[g]);
      }
  }
  for (int i = 0; i <= ne; ++i) eptr[i] = static_cast<idx_t>(i) * nc;
  idx_t e = ne, ncommon = mesh.dim == 2 ? 2 : (mesh.type == CellType::hex8 ? 4 : 3);
  idx_t nparts = nparts_in, objval = 0;
  std::vector<idx_t> out(ne), npart(nn);
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = seed;
  options[METIS_OPTION_NUMBERING] = 0;
  if (contiguous) options[METIS_OPTION_CONTIG] = 1;
  if (objective == PartitionObjective::area) {
    split_cells_by_area(mesh, cells, nparts, options, out.data());
  } else {
    options[METIS_OPTION_OBJTYPE] =
        objective == PartitionObjective::volume ? METIS_OBJTYPE_VOL : METIS_OBJTYPE_CUT;
    metis_check(METIS_PartMeshDual(&e, &nn, eptr.data(), eind.data(), nullptr, nullptr, &ncommon,
                                   &nparts, nullptr, options, &objval, out.data(), npart.data()),
                "mesh");
  }
  for (int i = 0; i < ne; ++i) part[cells ? (*cells)[i] : i] = out[i];
}

// The parts of a body's split that are a mechanism or in pieces. hinged: some part's cells are
// joined only through single nodes (2D) or edges (3D) somewhere (fewer components when cells
// that share any node are joined than when only cells that share a facet are): two pieces
// hinged at a node, whose stiffness the kernel of rigid body motions does not make regular.
// pieces: some part falls into pieces that share no node (METIS's parts need not be
// connected): solved right, each piece with its own rigid motions, but a larger coarse problem
// and a worse-conditioned one. `facets`: all_facets(mesh); node_cell_offset and node_cell_list:
// the cells around each node, as MeshPartition holds them.
struct SplitDefects {
  bool hinged = false, pieces = false;
};
SplitDefects split_defects(const Mesh& mesh, const std::vector<int>& cells,
                           const std::vector<idx_t>& part,
                           const std::vector<std::pair<FacetKey, int>>& facets,
                           const std::vector<int>& node_cell_offset,
                           const std::vector<int>& node_cell_list) {
  std::vector<int> local(mesh.num_cells(), -1);
  for (size_t i = 0; i < cells.size(); ++i) local[cells[i]] = static_cast<int>(i);
  auto components = [&](auto&& join_all) {
    std::vector<int> parent(cells.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto root = [&](int a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    join_all([&](int a, int b) {
      if (local[a] < 0 || local[b] < 0 || part[a] != part[b]) return;
      const int ra = root(local[a]), rb = root(local[b]);
      if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
    });
    int n = 0;
    for (size_t i = 0; i < cells.size(); ++i) n += root(static_cast<int>(i)) == static_cast<int>(i);
    return n;
  };
  const int by_facet = components([&](auto join) {
    for (size_t i = 1; i < facets.size(); ++i)
      if (facets[i].first == facets[i - 1].first) join(facets[i].second, facets[i - 1].second);
  });
  const int by_node = components([&](auto join) {
    // At each node, each of the given cells is joined to the first given cell of its part met
    // before it there. Linear in the cells' node lists.
    for (size_t v = 0; v + 1 < node_cell_offset.size(); ++v)
      for (int i = node_cell_offset[v] + 1; i < node_cell_offset[v + 1]; ++i) {
        const int e = node_cell_list[i];
        if (local[e] < 0) continue;
        for (int j = node_cell_offset[v]; j < i; ++j) {
          const int f = node_cell_list[j];
          if (local[f] >= 0 && part[f] == part[e]) {
            join(e, f);
            break;
          }
        }
      }
  });
  std::vector<char> used(cells.size(), 0);
  int parts = 0;
  for (int e : cells)
    if (!used[part[e]]) used[part[e]] = 1, ++parts;
  SplitDefects defects;
  defects.hinged = by_node < by_facet;
  defects.pieces = by_node > parts;
  return defects;
}

// Repairs a split whose parts are in pieces or hinged (split_defects) by moving pieces: in every
// part, the cells joined through facets form pieces; all but the largest move to the part they
// share the most facets with (the lowest part number on a tie), in up to three passes. Every part
// then keeps one piece joined through facets, so it is neither hinged nor in pieces. Returns the
// cells moved, or -1, leaving `part` as it was, when a piece shares no facet with another part (a
// body joined only through nodes or edges), the moves would leave a part over twice the mean or
// move more than max_share of the cells. `facets`: all_facets(mesh). Deterministic: it depends
// on the cells' order only.
long repair_split(const std::vector<int>& cells, std::vector<idx_t>& part,
                  const std::vector<std::pair<FacetKey, int>>& facets, double max_share) {
  std::vector<int> local(part.size(), -1);
  for (size_t i = 0; i < cells.size(); ++i) local[cells[i]] = static_cast<int>(i);
  // Facet neighbours within the region (pairs of local indices).
  std::vector<std::pair<int, int>> nb;
  for (size_t i = 1; i < facets.size(); ++i)
    if (facets[i].first == facets[i - 1].first) {
      const int a = local[facets[i].second], b = local[facets[i - 1].second];
      if (a >= 0 && b >= 0) nb.push_back({a, b});
    }
  const int n = static_cast<int>(cells.size());
  std::vector<idx_t> p(n);
  for (int i = 0; i < n; ++i) p[i] = part[cells[i]];
  idx_t nparts = 0;
  for (idx_t q : p) nparts = std::max(nparts, q + 1);
  for (int pass = 0; pass < 3; ++pass) {
    std::vector<int> parent(n);
    std::iota(parent.begin(), parent.end(), 0);
    auto root = [&](int a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    for (const auto& [a, b] : nb)
      if (p[a] == p[b]) {
        const int ra = root(a), rb = root(b);
        if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
      }
    std::vector<int> size(n, 0);
    for (int i = 0; i < n; ++i) ++size[root(i)];
    std::vector<int> largest(nparts, -1);  // each part's largest piece (root)
    for (int i = 0; i < n; ++i)
      if (root(i) == i && (largest[p[i]] < 0 || size[i] > size[largest[p[i]]])) largest[p[i]] = i;
    std::map<int, std::map<idx_t, int>> shared;  // piece -> other part -> facets
    bool any = false;
    for (int i = 0; i < n; ++i) any = any || (root(i) == i && largest[p[i]] != i);
    if (!any) {
      std::vector<long long> count(nparts, 0);
      for (idx_t q : p) ++count[q];
      if (*std::max_element(count.begin(), count.end()) * nparts > 2 * static_cast<long long>(n))
        return -1;
      long moved = 0;
      for (int i = 0; i < n; ++i) moved += part[cells[i]] != p[i];
      if (static_cast<double>(moved) > max_share * n) return -1;
      for (int i = 0; i < n; ++i) part[cells[i]] = p[i];
      return moved;
    }
    for (const auto& [a, b] : nb)
      if (p[a] != p[b]) {
        const int ra = root(a), rb = root(b);
        if (largest[p[a]] != ra) ++shared[ra][p[b]];
        if (largest[p[b]] != rb) ++shared[rb][p[a]];
      }
    std::vector<idx_t> to(n, -1);
    for (int i = 0; i < n; ++i) {
      if (root(i) != i || largest[p[i]] == i) continue;
      const auto it = shared.find(i);
      if (it == shared.end()) return -1;  // joined to no other part through a facet
      int best = -1;
      for (const auto& [q, c] : it->second)
        if (c > best) best = c, to[i] = q;
    }
    for (int i = 0; i < n; ++i)
      if (to[root(i)] >= 0) p[i] = to[root(i)];
  }
  return -1;
}

// The cells' facet neighbours (CSR over all cells) from all_facets(mesh).
struct CellNeighbours {
  std::vector<int> offset, list;
};
CellNeighbours facet_neighbours(int ne, const std::vector<std::pair<FacetKey, int>>& facets) {
  CellNeighbours g;
  g.offset.assign(ne + 1, 0);
  for (size_t i = 1; i < facets.size(); ++i)
    if (facets[i].first == facets[i - 1].first)
      ++g.offset[facets[i].second + 1], ++g.offset[facets[i - 1].second + 1];
  for (int e = 0; e < ne; ++e) g.offset[e + 1] += g.offset[e];
  g.list.resize(g.offset[ne]);
  std::vector<int> pos(g.offset.begin(), g.offset.end() - 1);
  for (size_t i = 1; i < facets.size(); ++i)
    if (facets[i].first == facets[i - 1].first) {
      const int a = facets[i].second, b = facets[i - 1].second;
      g.list[pos[a]++] = b, g.list[pos[b]++] = a;
    }
  return g;
}

// The cells' centroids (3 per cell: the mean of its nodes, fem's cell_centroid).
std::vector<double> cell_centroids(const Mesh& mesh) {
  const int ne = mesh.num_cells(), nc = cell_nodes(mesh.type);
  std::vector<double> c(3 * static_cast<size_t>(ne));
  double x[3 * 8];
  for (int e = 0; e < ne; ++e) {
    for (int a = 0; a < nc; ++a)
      for (int d = 0; d < 3; ++d)
        x[3 * a + d] =
            mesh.coords[3 * static_cast<size_t>(mesh.cells[static_cast<size_t>(e) * nc + a]) + d];
    const std::array<double, 3> ce = cell_centroid(mesh.type, x);
    std::copy(ce.begin(), ce.end(), c.begin() + 3 * static_cast<size_t>(e));
  }
  return c;
}

// Compact parts (partition.hpp, PartitionShape::compact): a split of the cells `region` into k
// parts (`part`, values 0..k-1 on the region's cells) moved toward a centroidal power diagram of
// the cells' centroids with equal cell counts: Lloyd's iteration with a weight per part, the
// balanced k-means of geometric partitioners. A round computes each part's centroid c_j and its
// cells' mean squared distance I_j from it, then sweeps: every cell on a part boundary goes to
// the part, among its own and its facet neighbours', that minimizes |x - c_j|^2 - w_j (x: the
// cell's centroid; ties keep the cell where it is, then take the lower part); after each sweep
// w_j += kCompactStep (t - n_j) / t I_j (t: the mean count, n_j: the part's count), so that the
// counts move toward t, by a step scaled to the part's size. A round ends when the counts are
// within kCompactImbalance of t, or after kCompactBalanceSweeps sweeps; the iteration, when a
// balanced round moved fewer than kCompactSettled of the cells, or after kCompactRounds rounds.
// A sweep reads the last sweep's parts only, so it runs on the threads and its result does not
// depend on them. One sweep costs O(cells x facets per cell). Returns the sweeps, or -1 with
// `part` unchanged when the counts did not come within kCompactImbalance of t.
// `local`: -1 for every cell on entry, and so on return (the region's cells' indices meanwhile).
int compact_split(const std::vector<int>& region, int k, std::vector<idx_t>& part,
                  const std::vector<double>& centroid, const CellNeighbours& g,
                  std::vector<int>& local) {
  const int n = static_cast<int>(region.size());
  if (k <= 1 || n <= k) return 0;
  struct Restore {
    const std::vector<int>& region;
    std::vector<int>& local;
    ~Restore() {
      for (int e : region) local[e] = -1;
    }
  } restore{region, local};
  for (int i = 0; i < n; ++i) local[region[i]] = i;
  std::vector<int> p(n), q(n);
  for (int i = 0; i < n; ++i) p[i] = static_cast<int>(part[region[i]]);
  const double t = static_cast<double>(n) / k;
  const long hi = static_cast<long>(std::floor(kCompactImbalance * t));
  std::vector<double> c(3 * static_cast<size_t>(k)), w(k, 0.0), inertia(k);
  std::vector<long> count(k);
  const auto x = [&](int i, int d) { return centroid[3 * static_cast<size_t>(region[i]) + d]; };
  const auto balanced = [&] {
    return *std::max_element(count.begin(), count.end()) <= hi &&
           *std::min_element(count.begin(), count.end()) > 0;
  };
  int sweeps = 0;
  for (int round = 0; round < kCompactRounds; ++round) {
    std::fill(c.begin(), c.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (int i = 0; i < n; ++i) {
      ++count[p[i]];
      for (int d = 0; d < 3; ++d) c[3 * p[i] + d] += x(i, d);
    }
    for (int j = 0; j < k; ++j)
      for (int d = 0; d < 3; ++d) c[3 * j + d] /= std::max<long>(1, count[j]);
    std::fill(inertia.begin(), inertia.end(), 0.0);
    for (int i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d)
        inertia[p[i]] += (x(i, d) - c[3 * p[i] + d]) * (x(i, d) - c[3 * p[i] + d]);
    for (int j = 0; j < k; ++j) inertia[j] /= std::max<long>(1, count[j]);
    long moved_round = 0;
    for (int s = 0; s < kCompactBalanceSweeps; ++s) {
      ++sweeps;
      long moved = 0;
#pragma omp parallel for schedule(static) reduction(+ : moved)  // each cell reads the last sweep's parts
      for (int i = 0; i < n; ++i) {
        const int e = region[i], own = p[i];
        int best = own;
        double best_d = 0;
        bool first = true;
        for (int a = g.offset[e]; a < g.offset[e + 1]; ++a) {
          const int f = local[g.list[a]];
          if (f < 0 || p[f] == own) continue;
          if (first) {
            best_d = -w[own];
            for (int d = 0; d < 3; ++d)
              best_d += (x(i, d) - c[3 * own + d]) * (x(i, d) - c[3 * own + d]);
            first = false;
          }
          const int j = p[f];
          double dj = -w[j];
          for (int d = 0; d < 3; ++d) dj += (x(i, d) - c[3 * j + d]) * (x(i, d) - c[3 * j + d]);
          if (dj < best_d || (dj == best_d && j < best && best != own)) best = j, best_d = dj;
        }
        q[i] = best;
        moved += best != own;
      }
      p.swap(q);
      moved_round += moved;
      std::fill(count.begin(), count.end(), 0);
      for (int i = 0; i < n; ++i) ++count[p[i]];
      for (int j = 0; j < k; ++j) w[j] += kCompactStep * (t - count[j]) / t * inertia[j];
      if (balanced()) break;
    }
    if (balanced() && moved_round < kCompactSettled * n) break;
  }
  if (!balanced()) return -1;
  for (int i = 0; i < n; ++i) part[region[i]] = p[i];
  return sweeps;
}

// Subdomains per body, proportional to the bodies' cell counts (largest remainders, at least
// one each), summing to `subdomains`.
std::vector<int> parts_per_body(const std::vector<long long>& cells_of_body, int subdomains) {
  const int nb = static_cast<int>(cells_of_body.size());
  long long total = 0;
  for (long long c : cells_of_body) total += c;
  std::vector<int> n(nb, 1);
  int left = subdomains - nb;
  std::vector<std::pair<double, int>> rem;
  for (int b = 0; b < nb; ++b) {
    const double share = static_cast<double>(subdomains) * cells_of_body[b] / total - 1.0;
    const int whole = std::max(0, std::min(left, static_cast<int>(std::floor(share))));
    n[b] += whole;
    left -= whole;
    rem.push_back({-(share - whole), b});
  }
  std::sort(rem.begin(), rem.end());
  for (int i = 0; left > 0; i = (i + 1) % nb, --left) ++n[rem[i].second];
  for (int b = 0; b < nb; ++b) n[b] = static_cast<int>(std::min<long long>(n[b], cells_of_body[b]));
  return n;
}

}  // namespace

double stretched_cell_share(const Mesh& mesh) {
  const int ne = mesh.num_cells();
  if (ne == 0) return 0;
  long long stretched = 0;
  double m[6];
  for (int e = 0; e < ne; ++e) {
    const int nf = cell_facet_measures(mesh, e, m);
    const auto [lo, hi] = std::minmax_element(m, m + nf);
    if (*hi >= kStretchRatio * *lo) ++stretched;
  }
  return static_cast<double>(stretched) / ne;
}

PartitionObjective parse_partition_objective(const std::string& name) {
  return parse_name(kPartitionObjectiveNames, name, "partition objective");
}

std::string to_string(PartitionObjective objective) {
  return name_of(kPartitionObjectiveNames, objective);
}

PartitionShape parse_partition_shape(const std::string& name) {
  return parse_name(kPartitionShapeNames, name, "partition shape");
}

std::string to_string(PartitionShape shape) { return name_of(kPartitionShapeNames, shape); }

ClusterSplit parse_cluster_split(const std::string& name) {
  return parse_name(kClusterSplitNames, name, "cluster split");
}

std::string to_string(ClusterSplit split) { return name_of(kClusterSplitNames, split); }

std::vector<int> cluster_subdomains(const std::vector<std::map<int, int>>& adjacency,
                                    const std::vector<int>& body_first, int cluster_size,
                                    int seed) {
  const int subdomains = body_first.back(), nb = static_cast<int>(body_first.size()) - 1;
  const int nclusters_target = (subdomains + cluster_size - 1) / cluster_size;
  std::vector<int> cpart(subdomains, 0);
  if (cluster_size == 1) {
    std::iota(cpart.begin(), cpart.end(), 0);
    return cpart;
  }
  int cluster_offset = 0;
  for (int b = 0; b < nb; ++b) {
    const int first = body_first[b], ns = body_first[b + 1] - first;
    const int target = nb == 1 ? nclusters_target : (ns + cluster_size - 1) / cluster_size;
    if (target > 1) {
      std::vector<idx_t> xadj(ns + 1, 0), adjncy, adjwgt;
      for (int s = 0; s < ns; ++s) {
        for (const auto& [t, w] : adjacency[first + s])
          adjncy.push_back(t - first), adjwgt.push_back(w);
        xadj[s + 1] = static_cast<idx_t>(adjncy.size());
      }
      idx_t nv = ns, ncon = 1, nparts = target, objval = 0;
      std::vector<idx_t> out(ns);
      idx_t options[METIS_NOPTIONS];
      METIS_SetDefaultOptions(options);
      options[METIS_OPTION_SEED] = seed;
      metis_check(METIS_PartGraphKway(&nv, &ncon, xadj.data(), adjncy.data(), nullptr, nullptr,
                                      adjwgt.data(), &nparts, nullptr, nullptr, options, &objval,
                                      out.data()),
                  "subdomain graph into clusters");
      // METIS 5.1's k-way split of a small graph into many parts can come back degenerate and
      // still report success: the 64 parts of a METIS-split cube into 32 clusters came back as
      // one cluster of 64, which silently turned cluster_size = 2 into one cluster. A split
      // whose largest cluster is more than twice the asked size is redone by recursive
      // bisection, which does not fail so (Cli.ClustersOfMetisPartsHaveTheAskedSize).
      std::vector<int> count(target, 0);
      for (int s = 0; s < ns; ++s) ++count[out[s]];
      if (*std::max_element(count.begin(), count.end()) > 2 * ((ns + target - 1) / target))
        metis_check(METIS_PartGraphRecursive(&nv, &ncon, xadj.data(), adjncy.data(), nullptr,
                                             nullptr, adjwgt.data(), &nparts, nullptr, nullptr,
                                             options, &objval, out.data()),
                    "subdomain graph into clusters");
      for (int s = 0; s < ns; ++s) cpart[first + s] = cluster_offset + static_cast<int>(out[s]);
    } else {
      for (int s = 0; s < ns; ++s) cpart[first + s] = cluster_offset;
    }
    cluster_offset += std::max(target, 1);
  }
  return cpart;
}

ClusterOrder order_by_cluster(const std::vector<int>& cluster) {
  const int subdomains = static_cast<int>(cluster.size());
  std::vector<int> cl_count(subdomains, 0), cl_new(cl_count.size(), -1);
  for (int s = 0; s < subdomains; ++s) ++cl_count[cluster[s]];
  int nclusters = 0;
  for (size_t c = 0; c < cl_count.size(); ++c)
    if (cl_count[c] > 0) cl_new[c] = nclusters++;
  std::vector<int> order(subdomains);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return cl_new[cluster[a]] < cl_new[cluster[b]]; });
  ClusterOrder out;
  out.new_id.resize(subdomains);
  for (int i = 0; i < subdomains; ++i) out.new_id[order[i]] = i;
  out.cluster_first.assign(nclusters + 1, 0);
  for (int s = 0; s < subdomains; ++s) ++out.cluster_first[cl_new[cluster[s]] + 1];
  for (int c = 0; c < nclusters; ++c) out.cluster_first[c + 1] += out.cluster_first[c];
  return out;
}

namespace {
// MeshPartition::groups from the mesh's groups and the partition's copies and cells.
void index_groups(const Mesh& mesh, MeshPartition& p) {
  p.groups.assign(p.num_subdomains, {});
  const auto add = [](std::vector<std::pair<std::string, std::vector<int>>>& list,
                      const std::string& name, int value) {
    if (list.empty() || list.back().first != name) list.emplace_back(name, std::vector<int>());
    list.back().second.push_back(value);
  };
  for (const auto& [name, gn] : mesh.node_groups)
    for (int g : gn)
      for (int c = p.copy_offset[g]; c < p.copy_offset[g + 1]; ++c)
        add(p.groups[p.copy_list[c]].nodes, name, g);
  for (const auto& [name, cg] : mesh.cell_groups)
    for (int e : cg) add(p.groups[p.cell_subdomain[e]].cells, name, e);
  const int nc = cell_nodes(mesh.type);
  for (const auto& [name, fg] : mesh.facet_groups) {
    const int fn = fg.facet_nodes;
    for (size_t i = 0; i + fn <= fg.nodes.size(); i += fn) {
      int owner = -1;
      const int g0 = fg.nodes[i];
      for (int c = p.node_cell_offset[g0]; c < p.node_cell_offset[g0 + 1]; ++c) {
        const int e = p.node_cell_list[c];
        int hits = 0;
        for (int a = 0; a < nc; ++a)
          for (int b = 0; b < fn; ++b)
            hits += mesh.cells[static_cast<size_t>(e) * nc + a] == fg.nodes[i + b];
        if (hits == fn && (owner < 0 || p.cell_subdomain[e] < owner)) owner = p.cell_subdomain[e];
      }
      if (owner >= 0) add(p.groups[owner].facets, name, static_cast<int>(i / fn));
    }
  }
}
}  // namespace

long repair_parts(const Mesh& mesh, std::vector<int>& part, double max_share) {
  std::vector<int> cells(mesh.num_cells());
  std::iota(cells.begin(), cells.end(), 0);
  std::vector<idx_t> p(part.begin(), part.end());
  const long moved = repair_split(cells, p, all_facets(mesh), max_share);
  if (moved >= 0) part.assign(p.begin(), p.end());
  return moved;
}

MeshPartition partition_mesh(const Mesh& mesh, int subdomains, int cluster_size,
                             PartitionObjective objective, ClusterSplit split, int seed,
                             const std::vector<double>* cell_coefficient, double jump_ratio,
                             PartitionShape shape) {
  if (subdomains < 1) throw std::invalid_argument("decomposition.subdomains must be positive");
  if (cluster_size < 1) throw std::invalid_argument("decomposition.cluster_size must be positive");
  const int ne = mesh.num_cells(), nn = mesh.num_nodes(), nc = cell_nodes(mesh.type);
  if (subdomains > ne)
    throw std::invalid_argument("decomposition.subdomains = " + std::to_string(subdomains) +
                                " exceeds the " + std::to_string(ne) + " cells of the mesh");
  MeshPartition p;
  if (objective == PartitionObjective::automatic) {
    p.stretched_share = stretched_cell_share(mesh);
    objective = p.stretched_share >= kStretchedShare ? PartitionObjective::area
                                                     : PartitionObjective::volume;
  }
  p.objective = objective;
  p.num_bodies = find_bodies(mesh, p.cell_body);
  const int nb = p.num_bodies;
  if (subdomains < nb)
    throw std::invalid_argument("decomposition.subdomains = " + std::to_string(subdomains) +
                                " is fewer than the " + std::to_string(nb) +
                                " bodies of the mesh (a subdomain never spans two bodies)");
  // 1. Subdomains: METIS on the dual graph, of the whole mesh (one body) or of each body with
  // a share of the subdomains proportional to its cells (subdomain ids body-major). With
  // clusters split from the mesh (ClusterSplit::mesh), each body is first split into its
  // clusters and each cluster into its share of the body's subdomains (ids cluster-major).
  // A region (body or cluster) whose METIS split left a subdomain hinged at a node or in pieces
  // (METIS's parts need not be connected) is split again with connected parts asked for
  // (METIS_OPTION_CONTIG); other splits are kept as METIS gave them.
  p.cluster_split = split;
  std::vector<idx_t> part(ne, 0);
  std::vector<int> body_first(nb + 1, 0);  // first subdomain of each body
  const auto facets = all_facets(mesh);
  // The cells around each node (ascending), for the checks of the splits and for the model.
  p.node_cell_offset.assign(nn + 1, 0);
  for (int v : mesh.cells) ++p.node_cell_offset[v + 1];
  for (int k = 0; k < nn; ++k) p.node_cell_offset[k + 1] += p.node_cell_offset[k];
  p.node_cell_list.resize(mesh.cells.size());
  {
    std::vector<int> pos(p.node_cell_offset.begin(), p.node_cell_offset.end() - 1);
    for (int e = 0; e < ne; ++e)
      for (int a = 0; a < nc; ++a)
        p.node_cell_list[pos[mesh.cells[static_cast<size_t>(e) * nc + a]]++] = e;
  }
  const auto defects_of = [&](const std::vector<int>& region, const std::vector<idx_t>& out) {
    return split_defects(mesh, region, out, facets, p.node_cell_offset, p.node_cell_list);
  };
  std::vector<std::vector<int>> cells(nb);
  for (int e = 0; e < ne; ++e) cells[p.cell_body[e]].push_back(e);
  std::vector<long long> counts(nb);
  for (int b = 0; b < nb; ++b) counts[b] = static_cast<long long>(cells[b].size());
  const std::vector<int> n =
      nb == 1 ? std::vector<int>{subdomains} : parts_per_body(counts, subdomains);
  // Compact parts (compact_split) where asked: kept when the parts stay whole (a few cells in
  // pieces moved by repair_split) and the cut facets fall to kCompactGain of METIS's split's or
  // fewer; else METIS's split stays.
  CellNeighbours neighbours;
  std::vector<double> centroids;
  std::vector<char> inside;
  std::vector<int> local;
  const auto compact_region = [&](const std::vector<int>& region, int k, std::vector<idx_t>& out) {
    if (shape != PartitionShape::compact || k <= 1) return;
    if (centroids.empty()) {
      centroids = cell_centroids(mesh);
      neighbours = facet_neighbours(ne, facets);
      inside.assign(ne, 0);
      local.assign(ne, -1);
    }
    for (int e : region) inside[e] = 1;
    const auto cut = [&] {  // facets between two parts of the region, counted from both sides
      long c = 0;
      for (int e : region)
        for (int a = neighbours.offset[e]; a < neighbours.offset[e + 1]; ++a) {
          const int f = neighbours.list[a];
          c += inside[f] && out[e] != out[f];
        }
      return c;
    };
    const long cut_metis = cut();
    std::vector<idx_t> metis(region.size());
    for (size_t i = 0; i < region.size(); ++i) metis[i] = out[region[i]];
    bool kept = compact_split(region, k, out, centroids, neighbours, local) >= 0;
    if (kept) {
      const SplitDefects d = defects_of(region, out);
      if (d.hinged || d.pieces) {
        const long moved = repair_split(region, out, facets, kRepairShare);
        const SplitDefects left = moved >= 0 ? defects_of(region, out) : d;
        kept = moved >= 0 && !left.hinged && !left.pieces;
      }
    }
    kept = kept && static_cast<double>(cut()) <= kCompactGain * static_cast<double>(cut_metis);
    for (int e : region) inside[e] = 0;
    if (kept) {
      ++p.compact_splits;
    } else {
      ++p.compact_declined;
      for (size_t i = 0; i < region.size(); ++i) out[region[i]] = metis[i];
    }
  };
  // Splits the cells `region` (subset: nullptr for the whole mesh) into k parts of `out`.
  const auto split_region = [&](const std::vector<int>* subset, const std::vector<int>& region,
                                int k, std::vector<idx_t>& out, bool subdomain_parts,
                                const std::string& what) {
    split_cells(mesh, subset, k, objective, seed, out);
    const SplitDefects defects = k > 1 ? defects_of(region, out) : SplitDefects{};
    if (!defects.hinged && !defects.pieces) return compact_region(region, k, out);
    // A few cells in pieces: moved to a neighbouring part (repair_split); METIS's split is kept
    // otherwise. Larger defects: METIS again with connected parts asked for.
    const std::vector<idx_t> metis_split = out;
    const long moved = repair_split(region, out, facets, kRepairShare);
    if (moved >= 0) {
      const SplitDefects left = defects_of(region, out);
      if (!left.hinged && !left.pieces) {
        p.repaired_cells += moved;
        return compact_region(region, k, out);
      }
      out = metis_split;
    }
    ++p.contiguous_splits;
    split_cells(mesh, subset, k, objective, seed, out, true);
    if (subdomain_parts && defects_of(region, out).hinged)
      throw std::invalid_argument("METIS could not split " + what + " into " + std::to_string(k) +
                                  " subdomains without one hinged at a node (a mechanism): use "
                                  "fewer subdomains");
    compact_region(region, k, out);
  };
  // Coefficient jumps: each cell's neighbours through facets without a jump (none at a jump).
  const bool jumps = cell_coefficient && jump_ratio > 1;
  if (jumps && static_cast<int>(cell_coefficient->size()) != ne)
    throw std::invalid_argument("partition_mesh: one coefficient per cell expected");
  std::vector<int> smooth_offset, smooth_list;
  bool any_jump = false;
  if (jumps) {
    const std::vector<double>& c = *cell_coefficient;
    std::vector<std::pair<int, int>> pairs;
    for (size_t i = 0; i < facets.size();) {
      size_t j = i;
      while (j < facets.size() && facets[j].first == facets[i].first) ++j;
      if (j - i == 2) {
        const int a = facets[i].second, b = facets[i + 1].second;
        const double lo = std::min(c[a], c[b]), hi = std::max(c[a], c[b]);
        if (hi > jump_ratio * lo)
          any_jump = true;
        else
          pairs.push_back({a, b});
      }
      i = j;
    }
    smooth_offset.assign(ne + 1, 0);
    for (const auto& [a, b] : pairs) ++smooth_offset[a + 1], ++smooth_offset[b + 1];
    for (int e = 0; e < ne; ++e) smooth_offset[e + 1] += smooth_offset[e];
    smooth_list.resize(smooth_offset[ne]);
    std::vector<int> pos(smooth_offset.begin(), smooth_offset.end() - 1);
    for (const auto& [a, b] : pairs) smooth_list[pos[a]++] = b, smooth_list[pos[b]++] = a;
  }
  // The regions of a set of cells: connected through facets without a jump (breadth first,
  // in the order of the set's cells).
  std::vector<int> in_set(any_jump ? ne : 0, 0), seen(any_jump ? ne : 0, 0);
  const auto regions_of = [&](const std::vector<int>& set) {
    std::vector<std::vector<int>> regions;
    for (int e : set) in_set[e] = 1;
    for (int e0 : set) {
      if (seen[e0]) continue;
      std::vector<int> region{e0};
      seen[e0] = 1;
      for (size_t q = 0; q < region.size(); ++q) {
        const int e = region[q];
        for (int k = smooth_offset[e]; k < smooth_offset[e + 1]; ++k) {
          const int f = smooth_list[k];
          if (in_set[f] && !seen[f]) seen[f] = 1, region.push_back(f);
        }
      }
      regions.push_back(std::move(region));
    }
    for (int e : set) in_set[e] = 0, seen[e] = 0;
    return regions;
  };
  // Splits the cells `region` (subset: nullptr for the whole mesh) into k subdomains of `out`:
  // each of its regions between jumps into its own share of them where it has enough.
  const auto split_subdomains = [&](const std::vector<int>* subset, const std::vector<int>& region,
                                    int k, std::vector<idx_t>& out, const std::string& what) {
    if (any_jump && k > 1) {
      std::vector<std::vector<int>> regions = regions_of(region);
      const int nr = static_cast<int>(regions.size());
      if (nr > 1 && nr <= k) {
        std::vector<long long> counts(nr);
        for (int r = 0; r < nr; ++r) counts[r] = static_cast<long long>(regions[r].size());
        const std::vector<int> kr = parts_per_body(counts, k);
        // Taken when the shares add up and no region's subdomains average more than
        // kJumpImbalance times the set's mean (many small regions would leave the rest few).
        int total = 0;
        double largest = 0;
        for (int r = 0; r < nr; ++r)
          total += kr[r], largest = std::max(largest, static_cast<double>(counts[r]) / kr[r]);
        if (total == k && largest <= kJumpImbalance * static_cast<double>(region.size()) / k) {
          for (int r = 0, offset = 0; r < nr; offset += kr[r], ++r) {
            split_region(&regions[r], regions[r], kr[r], out, true,
                         what + ", region " + std::to_string(r + 1) + " between jumps");
            for (int e : regions[r]) out[e] += offset;
          }
          p.jump_regions += nr;
          return;
        }
      }
      if (nr > 1) ++p.jump_splits_declined;
    }
    split_region(subset, region, k, out, true, what);
  };
  const bool by_mesh = split == ClusterSplit::mesh && cluster_size > 1;
  std::vector<int> cluster_of;  // by_mesh: the cluster of each subdomain
  for (int b = 0; b < nb; ++b) {
    const std::vector<int>* subset = nb == 1 ? nullptr : &cells[b];
    const std::string body = "body " + std::to_string(b + 1);
    const int nclusters = (n[b] + cluster_size - 1) / cluster_size;
    const int first_cluster = cluster_of.empty() ? 0 : cluster_of.back() + 1;
    if (!by_mesh || nclusters == 1) {
      split_subdomains(subset, cells[b], n[b], part, body);
      for (int e : cells[b]) part[e] += body_first[b];
      if (by_mesh) cluster_of.insert(cluster_of.end(), n[b], first_cluster);
    } else {
      std::vector<idx_t> cpart(ne, 0);
      split_region(subset, cells[b], nclusters, cpart, false, body);
      std::vector<std::vector<int>> in(nclusters);
      for (int e : cells[b]) in[cpart[e]].push_back(e);
      std::vector<long long> cluster_cells(nclusters);
      for (int c = 0; c < nclusters; ++c) {
        if (in[c].empty())
          throw std::invalid_argument("METIS left a cluster of " + body +
                                      " empty: use fewer subdomains for this mesh");
        cluster_cells[c] = static_cast<long long>(in[c].size());
      }
      const std::vector<int> k = parts_per_body(cluster_cells, n[b]);
      for (int c = 0, offset = body_first[b]; c < nclusters; offset += k[c], ++c) {
        split_subdomains(&in[c], in[c], k[c], part,
                         "cluster " + std::to_string(first_cluster + c) + " (" + body + ")");
        for (int e : in[c]) part[e] += offset;
        cluster_of.insert(cluster_of.end(), k[c], first_cluster + c);
      }
    }
    body_first[b + 1] = body_first[b] + n[b];
  }
  {
    if (body_first[nb] != subdomains)
      throw std::invalid_argument(
          "decomposition.subdomains = " + std::to_string(subdomains) +
          " cannot be shared among the bodies of the mesh (a body has fewer cells than its share)");
  }
  std::vector<int> count(subdomains, 0);
  for (int e = 0; e < ne; ++e) ++count[part[e]];
  for (int s = 0; s < subdomains; ++s)
    if (count[s] == 0)
      throw std::invalid_argument("METIS left subdomain " + std::to_string(s) +
                                  " empty: use fewer subdomains for this mesh");

  // Copies per node (old ids).
  std::vector<std::vector<int>> node_subs(nn);
  for (int e = 0; e < ne; ++e)
    for (int a = 0; a < nc; ++a) {
      auto& v = node_subs[mesh.cells[static_cast<size_t>(e) * nc + a]];
      if (std::find(v.begin(), v.end(), static_cast<int>(part[e])) == v.end()) v.push_back(part[e]);
    }

  // 2. Clusters: as split from the mesh, or METIS on the subdomain graph, of each body apart.
  std::vector<std::map<int, int>> adj;
  if (cluster_size > 1 && !by_mesh) {
    adj.resize(subdomains);
    for (const auto& v : node_subs)
      for (size_t i = 0; i < v.size(); ++i)
        for (size_t j = 0; j < v.size(); ++j)
          if (i != j) ++adj[v[i]][v[j]];
  }
  const ClusterOrder order = order_by_cluster(
      by_mesh ? cluster_of : cluster_subdomains(adj, body_first, cluster_size, seed));
  const std::vector<int>& new_id = order.new_id;
  p.num_subdomains = subdomains;
  p.num_clusters = static_cast<int>(order.cluster_first.size()) - 1;
  p.cluster_first = order.cluster_first;
  p.cell_subdomain.resize(ne);
  p.subdomain_cells.assign(subdomains, {});
  for (int e = 0; e < ne; ++e) {
    p.cell_subdomain[e] = new_id[part[e]];
    p.subdomain_cells[p.cell_subdomain[e]].push_back(e);
  }
  p.copy_offset.assign(nn + 1, 0);
  for (int k = 0; k < nn; ++k) {
    auto& v = node_subs[k];
    for (int& s : v) s = new_id[s];
    std::sort(v.begin(), v.end());
    p.copy_offset[k + 1] = p.copy_offset[k] + static_cast<int>(v.size());
  }
  p.copy_list.reserve(p.copy_offset[nn]);
  for (const auto& v : node_subs) p.copy_list.insert(p.copy_list.end(), v.begin(), v.end());
  index_groups(mesh, p);
  // Domain boundary: nodes of facets that belong to one cell only.
  p.on_boundary.assign(nn, 0);
  for (size_t i = 0; i < facets.size();) {
    size_t j = i;
    while (j < facets.size() && facets[j].first == facets[i].first) ++j;
    if (j - i == 1)
      for (int v : facets[i].first)
        if (v >= 0) p.on_boundary[v] = 1;
    i = j;
  }
  return p;
}

SubdomainMesh extract_subdomain(const Mesh& mesh, const MeshPartition& p, int s) {
  SubdomainMesh m;
  const int nc = cell_nodes(mesh.type);
  m.id = s;
  m.cluster = static_cast<int>(std::upper_bound(p.cluster_first.begin(), p.cluster_first.end(), s) -
                               p.cluster_first.begin()) -
              1;
  m.dim = mesh.dim;
  m.type = mesh.type;
  const auto& cells = p.subdomain_cells[s];
  std::vector<int> nodes;
  for (int e : cells)
    for (int a = 0; a < nc; ++a) nodes.push_back(mesh.cells[static_cast<size_t>(e) * nc + a]);
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  auto local = [&](int g) {
    auto it = std::lower_bound(nodes.begin(), nodes.end(), g);
    return (it != nodes.end() && *it == g) ? static_cast<int>(it - nodes.begin()) : -1;
  };
  const int nn = static_cast<int>(nodes.size());
  m.global_node.assign(nodes.begin(), nodes.end());
  m.coords.resize(3 * static_cast<size_t>(nn));
  m.copy_offset.assign(nn + 1, 0);
  m.on_boundary.resize(nn);
  for (int k = 0; k < nn; ++k) {
    const int g = nodes[k];
    for (int d = 0; d < 3; ++d) m.coords[3 * k + d] = mesh.coords[3 * static_cast<size_t>(g) + d];
    m.copy_list.insert(m.copy_list.end(), p.copy_list.begin() + p.copy_offset[g],
                       p.copy_list.begin() + p.copy_offset[g + 1]);
    m.copy_offset[k + 1] = static_cast<int>(m.copy_list.size());
    m.on_boundary[k] = p.on_boundary[g];
  }
  m.cells.reserve(cells.size() * nc);
  for (int e : cells)
    for (int a = 0; a < nc; ++a)
      m.cells.push_back(local(mesh.cells[static_cast<size_t>(e) * nc + a]));
  const auto& groups = p.groups.at(s);
  for (const auto& [name, gn] : groups.nodes) {
    std::vector<int>& l = m.node_groups[name];
    l.reserve(gn.size());
    for (int g : gn) l.push_back(local(g));
  }
  for (const auto& [name, cg] : groups.cells) {
    std::vector<int>& l = m.cell_groups[name];
    l.reserve(cg.size());
    for (int e : cg)
      l.push_back(
          static_cast<int>(std::lower_bound(cells.begin(), cells.end(), e) - cells.begin()));
  }
  for (const auto& [name, facets] : groups.facets) {
    const auto& fg = mesh.facet_groups.at(name);
    SubdomainMesh::FacetGroup& out = m.facet_groups[name];
    out.facet_nodes = fg.facet_nodes;
    out.nodes.reserve(facets.size() * fg.facet_nodes);
    for (int f : facets)
      for (int a = 0; a < fg.facet_nodes; ++a)
        out.nodes.push_back(local(fg.nodes[static_cast<size_t>(f) * fg.facet_nodes + a]));
  }
  return m;
}

}  // namespace htfeti
