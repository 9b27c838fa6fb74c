// One coarse step per Hessian product (paper, (12) and (15): H_rho = P F P + rho Q with
// P = I - Q, Q = G~^T (G~ G~^T)^{-1} G~; docs/method.md, "One coarse step per Hessian product").
//
// With S = G~ G~^T, E = F G~^T and C = G~ E = G~ F G~^T:
//     P F P v = (I - Q)(F v - E z1) = F v - E z1 - G~^T z2,
//     z1 = S^{-1} G~ v,   z2 = S^{-1} (G~ F v - C z1),
// so G~ v and G~ F v, both known once F v is, travel in one global reduction, and the two
// coarse solves follow each other on every rank with no communication between them. The
// separate form (P v, F, P) needs two reductions, each waiting for the one before.
//
// Forming E. Column (j, t) of E (cluster j, kernel vector t) is F applied to G~^T e_(j,t), whose
// support lies in the multipliers of j; F = sum_c B_c K_c^+ B_c^T spreads it to the multipliers
// of the clusters next to j (N[j]: j and the clusters sharing a row of B~ with it). For clusters
// at distance 4 or more in that graph these supports are disjoint, and no cluster's solve sees
// two of them, so a distance-3 colouring lets one F application form the columns of a whole
// colour: at an owned multiplier k the column is the one cluster of that colour in the union of
// N[c] over the clusters c touching k. An entry outside every candidate's neighbourhood must
// come out exactly zero, which is checked. C = G~ E is summed at the owners of the multipliers,
// from G~'s columns there and E's rows, per owner cluster in multiplier order and then in
// cluster order, so it does not depend on the number of ranks.
//
// Cost: setup, (colours x largest kernel dimension) applications of G~^T and F (about 16 x 1
// for a 2D Laplace box, 64 x 6 for 3D elasticity). Memory: E has one entry per (multiplier,
// kernel vector of a cluster within distance 1 of the multiplier's clusters): 12 per multiplier
// of a 2D Laplace box, about 216 in 3D elasticity. Per product: see hessian_from_Fv.
#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "htfeti/clock.hpp"
#include "htfeti/feti/coarse_space.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

namespace {

// Greedy colouring in cluster order such that clusters at distance <= 3 differ (the same on
// every rank: the graph is).
std::vector<int> distance3_colouring(const std::vector<std::vector<int>>& adj) {
  const int n = static_cast<int>(adj.size());
  std::vector<int> colour(n, -1), seen(n, -1), used;
  std::vector<int> frontier, next;
  for (int j = 0; j < n; ++j) {
    used.clear();
    frontier.assign(1, j);
    seen[j] = j;
    for (int depth = 0; depth < 3; ++depth) {
      next.clear();
      for (int a : frontier)
        for (int b : adj[a])
          if (seen[b] != j) {
            seen[b] = j;
            next.push_back(b);
            if (colour[b] >= 0) used.push_back(colour[b]);
          }
      frontier.swap(next);
    }
    std::sort(used.begin(), used.end());
    int c = 0;
    for (int u : used)
      if (u == c)
        ++c;
      else if (u > c)
        break;
    colour[j] = c;
  }
  return colour;
}
// Step 2 of build_coarse_image: the cluster graph, every rank the whole of it: clusters are
// adjacent when a multiplier touches both. Collective.
std::vector<std::vector<int>> cluster_graph(const std::vector<std::vector<int>>& touching, int ncl,
                                            MPI_Comm mc) {
  int P = 0;
  MPI_Comm_size(mc, &P);
  std::vector<long long> edges;
  for (const auto& t : touching)
    for (size_t a = 0; a < t.size(); ++a)
      for (size_t b = a + 1; b < t.size(); ++b)
        if (t[a] != t[b]) edges.push_back(static_cast<long long>(t[a]) * ncl + t[b]);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  int nedges = static_cast<int>(edges.size());
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Allgather(&nedges, 1, MPI_INT, counts.data(), 1, MPI_INT, mc);
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<long long> all_edges(disp[P]);
  MPI_Allgatherv(edges.data(), nedges, MPI_LONG_LONG, all_edges.data(), counts.data(), disp.data(),
                 MPI_LONG_LONG, mc);
  edges = {};
  std::vector<std::vector<int>> adj(ncl);
  for (long long e : all_edges) {
    const int a = static_cast<int>(e / ncl), b = static_cast<int>(e % ncl);
    adj[a].push_back(b), adj[b].push_back(a);
  }
  all_edges = {};
  for (auto& a : adj) {
    std::sort(a.begin(), a.end());
    a.erase(std::unique(a.begin(), a.end()), a.end());
  }
  return adj;
}

}  // namespace

// Step 1 of build_coarse_image: per owned multiplier, the clusters touching it (sorted), from
// (global multiplier, cluster) pairs of each rank's clusters sent to the multipliers' owners.
// Collective.
std::vector<std::vector<int>> CoarseSpace::clusters_touching_owned_rows() const {
  const int P = comm_.size(), n_own = m_.layout.n_owned();
  const MPI_Comm mc = comm_.raw();
  std::vector<std::vector<long long>> out(P);
  {
    std::vector<int> ks;
    for (size_t c = 0; c < rows_.size(); ++c) {
      ks.clear();
      for (int i = 0; i < members(static_cast<int>(c)); ++i)
        for (int k : m_.of_subdomain[sub_of(static_cast<int>(c), i)]) ks.push_back(k);
      std::sort(ks.begin(), ks.end());
      ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
      for (int k : ks) {
        out[m_.owner_rank[k]].push_back(m_.layout.global(k));
        out[m_.owner_rank[k]].push_back(first_cluster_ + c);
      }
    }
  }
  std::vector<int> scount(P), rcount(P), sdisp(P + 1, 0), rdisp(P + 1, 0);
  for (int r = 0; r < P; ++r) scount[r] = static_cast<int>(out[r].size());
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, mc);
  for (int r = 0; r < P; ++r)
    sdisp[r + 1] = sdisp[r] + scount[r], rdisp[r + 1] = rdisp[r] + rcount[r];
  std::vector<long long> sbuf(sdisp[P]), rbuf(rdisp[P]);
  for (int r = 0; r < P; ++r) std::copy(out[r].begin(), out[r].end(), sbuf.begin() + sdisp[r]);
  out = {};
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), MPI_LONG_LONG, rbuf.data(), rcount.data(),
                rdisp.data(), MPI_LONG_LONG, mc);
  sbuf = {};
  std::vector<std::vector<int>> touching(n_own);
  for (size_t i = 0; i < rbuf.size(); i += 2) {
    const int e = m_.layout.ext_index(rbuf[i]);
    if (e < 0 || e >= n_own) throw std::logic_error("coarse image: a pair for an unowned row");
    touching[e].push_back(static_cast<int>(rbuf[i + 1]));
  }
  rbuf = {};
  for (auto& t : touching) std::sort(t.begin(), t.end());
  return touching;
}

// Step 4 of build_coarse_image: C = G~ E. At each owned multiplier, G~'s column times E's row;
// partial sums per owner cluster in multiplier order, then in cluster order (as the coarse matrix
// G~ G~^T). Collective.
void CoarseSpace::assemble_image_coarse_matrix() {
  auto& im = image_;
  const std::vector<GItem> gcol = g_columns_at_owners();
  const std::vector<CoarseTriplet> mine =
      owner_cluster_sums(gcol, [&](size_t i, size_t j, std::vector<CoarseTriplet>& products) {
        const int e = m_.layout.ext_index(gcol[i].k);
        for (size_t a = i; a < j; ++a)
          for (int q = im.e_ptr[e]; q < im.e_ptr[e + 1]; ++q)
            products.push_back({gcol[i].k, gcol[a].row, im.e_col[q], gcol[a].g * im.e_val[q]});
      });
  const std::vector<CoarseTriplet> all = allgather_sorted(mine, comm_.raw());
  const int nc = dimension();
  im.c_ptr.assign(nc + 1, 0);
  im.c_col.clear(), im.c_val.clear();
  for (size_t p = 0; p < all.size();) {
    size_t q = p;
    double v = 0;
    for (; q < all.size() && all[q].a == all[p].a && all[q].b == all[p].b; ++q) v += all[q].v;
    im.c_col.push_back(all[p].b), im.c_val.push_back(v);
    ++im.c_ptr[all[p].a + 1];
    p = q;
  }
  for (int a = 0; a < nc; ++a) im.c_ptr[a + 1] += im.c_ptr[a];
}

void CoarseSpace::build_image(const std::function<void(const Vec&, Vec&)>& apply_F,
                              double memory_limit_mb) {
  const double t0 = seconds_now();
  const int n_own = m_.layout.n_owned(), ncl = layout_.num_clusters;
  const MPI_Comm mc = comm_.raw();

  // 1. The clusters touching each owned multiplier.
  std::vector<std::vector<int>> touching = clusters_touching_owned_rows();
  // 2. The cluster graph and its distance-3 colouring.
  const std::vector<std::vector<int>> adj = cluster_graph(touching, ncl, mc);
  const std::vector<int> colour = distance3_colouring(adj);
  const int ncolours = ncl ? *std::max_element(colour.begin(), colour.end()) + 1 : 0;

  // Candidate columns of each owned row: the clusters within distance 1 of a touching cluster.
  std::vector<std::vector<int>> cand(n_own);
  for (int e = 0; e < n_own; ++e) {
    auto& c = cand[e];
    for (int t : touching[e]) {
      c.push_back(t);
      c.insert(c.end(), adj[t].begin(), adj[t].end());
    }
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }
  touching = {};

  // 3. E, one (colour, kernel vector) at a time, into rows sized beforehand (each candidate
  //    contributes its kernel dimension), after a check that it fits.
  std::vector<int> dim(ncl);
  int kmax = 0;
  for (int j = 0; j < ncl; ++j) {
    dim[j] = first_[j + 1] - first_[j];
    kmax = std::max(kmax, dim[j]);
  }
  auto& im = image_;
  im.e_ptr.assign(n_own + 1, 0);
  for (int e = 0; e < n_own; ++e) {
    long long row = 0;
    for (int j : cand[e]) row += dim[j];
    im.e_ptr[e + 1] = static_cast<int>(im.e_ptr[e] + row);
  }
  {
    const double need_mb = 12.0 * im.e_ptr[n_own] / 1048576.0;
    const int machine_ranks = memory_limit_mb > 0 ? ranks_on_this_machine(mc) : 1;
    const double usable = usable_memory_mb(memory_limit_mb, machine_ranks);
    std::string error;
    if (available_memory_mb() > 0 && need_mb > usable)  // (0: /proc unreadable, unknown)
      error = "one coarse step per product needs E = F G~^T, " +
              std::to_string(std::lround(need_mb)) + " MB on rank " + std::to_string(comm_.rank()) +
              ", more than the " + std::to_string(std::lround(std::max(0.0, usable))) +
              " MB usable there; take two coarse steps per product (the default)";
    comm_.agree(error, true);
  }
  im.e_col.assign(im.e_ptr[n_own], 0);
  im.e_val.assign(im.e_ptr[n_own], 0.0);
  std::vector<int> fill(im.e_ptr.begin(), im.e_ptr.end() - 1);
  Vec z(dimension()), w, y;
  int applications = 0;
  for (int g = 0; g < ncolours; ++g)
    for (int t = 0; t < kmax; ++t) {
      z.setZero();
      bool any = false;
      for (int j = 0; j < ncl; ++j)
        if (colour[j] == g && dim[j] > t) z[first_[j] + t] = 1.0, any = true;
      if (!any) continue;
      apply_Gt(z, w);
      apply_F(w, y);
      ++applications;
      for (int e = 0; e < n_own; ++e) {
        int col = -1;
        for (int j : cand[e])
          if (colour[j] == g) {
            col = j;
            break;
          }
        if (col >= 0 && dim[col] > t) {
          im.e_col[fill[e]] = first_[col] + t;
          im.e_val[fill[e]++] = y[e];
        } else if (y[e] != 0.0) {
          throw std::logic_error(
              "coarse image: a column of F G~^T reached a multiplier outside its clusters' "
              "neighbourhood");
        }
      }
    }
  cand = {};
  std::vector<std::pair<int, double>> row;
  for (int e = 0; e < n_own; ++e) {  // columns in increasing order within each row
    if (fill[e] != im.e_ptr[e + 1]) throw std::logic_error("coarse image: a row of E incomplete");
    row.clear();
    for (int q = im.e_ptr[e]; q < im.e_ptr[e + 1]; ++q) row.push_back({im.e_col[q], im.e_val[q]});
    std::sort(row.begin(), row.end());
    for (size_t i = 0; i < row.size(); ++i)
      im.e_col[im.e_ptr[e] + i] = row[i].first, im.e_val[im.e_ptr[e] + i] = row[i].second;
  }

  // 4. C = G~ E.
  assemble_image_coarse_matrix();
  im.ab = Vec::Zero(2 * dimension());
  im.z1 = Vec::Zero(dimension());
  im.z2 = Vec::Zero(dimension());
  im.ext_in_second = Vec::Zero(m_.layout.n_ext());
  im.ext_out_second = Vec::Zero(m_.layout.n_ext());
  im.pairs_second = Vec::Zero(pairs_.size());
  im.stats.colours = ncolours;
  im.stats.F_applications = applications;
  im.stats.E_nonzeros = comm_.sum(static_cast<long long>(im.e_col.size()));
  im.stats.C_nonzeros = static_cast<long long>(im.c_col.size());
  im.built = true;
  im.stats.seconds = seconds_now() - t0;
}

void CoarseSpace::apply_image(const Vec& z, Vec& y) const {
  if (!image_.built) throw std::logic_error("apply_coarse_image before build_coarse_image");
  const int n = m_.layout.n_owned();
  y.resize(n);
#pragma omp parallel for schedule(static) if (n > 50000 && !omp_in_parallel())
  for (int e = 0; e < n; ++e) y[e] = image_row(e, z);
}

void CoarseSpace::hessian_from_Fv(const Vec& v, const Vec& fv, double rho, Vec& y, Vec& qv) {
  if (!image_.built) throw std::logic_error("hessian_from_Fv before build_coarse_image");
  auto& im = image_;
  const int nc = dimension(), n = m_.layout.n_owned();
  // [G~ v; G~ F v]: the rank's rows, a cluster at a time, then one reduction of both.
  const int ncl = local_clusters();
  m_.gather(v);
  im.ext_in_second.head(n) = fv;
  m_.layout.forward(im.ext_in_second.data());
  im.ab.setZero();
  double* a = im.ab.data();
  double* b = a + nc;
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    apply_rows(c, m_.ext_in.data(), a);
    apply_rows(c, im.ext_in_second.data(), b);
  }
  comm_.sum_in_place(im.ab.data(), 2 * nc);
  im.z1 = im.ab.head(nc);
  solve(im.z1);
  for (int row = 0; row < nc; ++row) {  // b - C z1
    double s = b[row];
    for (int q = im.c_ptr[row]; q < im.c_ptr[row + 1]; ++q) s -= im.c_val[q] * im.z1[im.c_col[q]];
    im.z2[row] = s;
  }
  solve(im.z2);
  // G~^T z1 (into m_.ext_out) and G~^T z2 (into ext_out_second), a cluster at a time.
#pragma omp parallel for schedule(dynamic, 16) if (outer_parallel_)
  for (int c = 0; c < ncl; ++c) {
    pairs_from_rows(c, im.z1.data(), pairs_.data());
    pairs_from_rows(c, im.z2.data(), im.pairs_second.data());
  }
  cluster_sum_.combine(pairs_.data(), m_.ext_out.data());
  cluster_sum_.combine(im.pairs_second.data(), im.ext_out_second.data());
  qv = m_.ext_out.head(n);
  y.resize(n);
#pragma omp parallel for schedule(static) if (n > 50000 && !omp_in_parallel())
  for (int e = 0; e < n; ++e)
    y[e] = fv[e] - image_row(e, im.z1) - im.ext_out_second[e] + rho * qv[e];
}

}  // namespace htfeti
