#include "htfeti/feti/constraints.hpp"

#include <cmath>

namespace htfeti {

std::vector<std::vector<double>> orthonormal_complement(const std::vector<double>& s) {
  // Generalized Helmert basis: row j = (s_1, ..., s_j, -(s_1^2 + ... + s_j^2) / s_{j+1}, 0, ...).
  const int t = static_cast<int>(s.size());
  std::vector<std::vector<double>> rows;
  double sum_sq = 0;
  for (int j = 1; j < t; ++j) {
    sum_sq += s[j - 1] * s[j - 1];
    std::vector<double> r(t, 0.0);
    for (int i = 0; i < j; ++i) r[i] = s[i];
    r[j] = -sum_sq / s[j];
    double norm = 0;
    for (double v : r) norm += v * v;
    norm = std::sqrt(norm);
    for (double& v : r) v /= norm;
    rows.push_back(std::move(r));
  }
  return rows;
}

namespace {

struct Copy {
  int subdomain, dof, cluster;
};

// Copies of grid node (gx, gy) of square q: one per subdomain whose closure holds it.
int node_copies(const Decomposition& dec, int q, int gx, int gy, Copy* out) {
  const int H = dec.H(), ns = dec.ns();
  int sxs[2], sys[2], nx = 0, ny = 0;
  if (gx % H == 0) {
    if (gx / H - 1 >= 0) sxs[nx++] = gx / H - 1;
    if (gx / H < ns) sxs[nx++] = gx / H;
  } else {
    sxs[nx++] = gx / H;
  }
  if (gy % H == 0) {
    if (gy / H - 1 >= 0) sys[ny++] = gy / H - 1;
    if (gy / H < ns) sys[ny++] = gy / H;
  } else {
    sys[ny++] = gy / H;
  }
  int k = 0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int s = dec.subdomain_id(q, sxs[i], sys[j]);
      out[k++] = {s, dec.local_node(gx - sxs[i] * H, gy - sys[j] * H), dec.cluster_of(s)};
    }
  return k;
}

}  // namespace

long long for_each_multiplier(const Decomposition& dec,
                              const std::function<void(const Multiplier&)>& fn) {
  const int n = dec.n(), H = dec.H();
  const Problem problem = dec.problem();
  const bool corners = dec.glue_corners(), averages = dec.glue_averages();
  Multiplier mult;
  long long index = 0;
  auto emit = [&](MultiplierKind kind) {
    mult.index = index++;
    mult.kind = kind;
    fn(mult);
  };
  Copy copies[4], right[4];

  for (int q = 0; q < dec.squares(); ++q)
    for (int gy = 0; gy <= n; ++gy) {
      const int step = (gy % H == 0) ? 1 : H;
      for (int gx = 0; gx <= n; gx += step) {
        const int k = node_copies(dec, q, gx, gy, copies);
        const bool edge_interior = (gx % H == 0) != (gy % H == 0);
        if (averages && edge_interior && k == 2 && copies[0].cluster == copies[1].cluster)
          continue;  // joined by the edge average: rows come with the edge below
        // Groups of copies that are equal primally (corner gluing within a cluster).
        int group[4], sizes[4], ngroups = 0;
        for (int i = 0; i < k; ++i) {
          group[i] = -1;
          if (corners && !edge_interior)
            for (int j = 0; j < i; ++j)
              if (copies[j].cluster == copies[i].cluster) group[i] = group[j];
          if (group[i] < 0) {
            group[i] = ngroups;
            sizes[ngroups++] = 0;
          }
          ++sizes[group[i]];
        }
        if (ngroups > 1) {
          std::vector<double> s(ngroups);
          for (int g = 0; g < ngroups; ++g) s[g] = std::sqrt(static_cast<double>(sizes[g]));
          for (const auto& row : orthonormal_complement(s)) {
            mult.entries.clear();
            for (int i = 0; i < k; ++i)
              mult.entries.push_back(
                  {copies[i].subdomain, copies[i].dof, row[group[i]] / s[group[i]]});
            emit(MultiplierKind::gluing);
          }
        }
        if (problem.dirichlet(q, gx, gy, n)) {
          mult.entries.clear();
          for (int i = 0; i < k; ++i)
            mult.entries.push_back({copies[i].subdomain, copies[i].dof, 1.0 / std::sqrt(k * 1.0)});
          emit(MultiplierKind::dirichlet);
        }
        if (problem.has_contact() && q == 0 && gx == n) {
          const int kr = node_copies(dec, 1, 0, gy, right);
          const double c = 1.0 / std::sqrt(1.0 / k + 1.0 / kr);
          mult.entries.clear();
          for (int i = 0; i < k; ++i)
            mult.entries.push_back({copies[i].subdomain, copies[i].dof, c / k});
          for (int i = 0; i < kr; ++i)
            mult.entries.push_back({right[i].subdomain, right[i].dof, -c / kr});
          mult.y = static_cast<double>(gy) / n;
          mult.scale = c;
          emit(MultiplierKind::contact);
          mult.y = 0;
          mult.scale = 1;
        }
      }
    }

  if (averages) {
    const int p = H - 1;
    const auto basis = orthonormal_complement(std::vector<double>(p, 1.0));
    const double r2 = 1.0 / std::sqrt(2.0);
    const int m = dec.m(), mm = m * m;
    for (int c = 0; c < dec.num_clusters(); ++c)
      for (int dir = 0; dir < 2; ++dir)  // 0: vertical edges (x-neighbours), 1: horizontal
        for (int ly = 0; ly < m - dir; ++ly)
          for (int lx = 0; lx < m - (1 - dir); ++lx) {
            const int si = c * mm + ly * m + lx;
            const int sj = dir == 0 ? si + 1 : si + m;
            for (const auto& row : basis) {
              mult.entries.clear();
              for (int t = 0; t < p; ++t) {
                const int di = dir == 0 ? dec.local_node(H, t + 1) : dec.local_node(t + 1, H);
                const int dj = dir == 0 ? dec.local_node(0, t + 1) : dec.local_node(t + 1, 0);
                mult.entries.push_back({si, di, row[t] * r2});
                mult.entries.push_back({sj, dj, -row[t] * r2});
              }
              emit(MultiplierKind::gluing);
            }
          }
  }
  return index;
}

std::vector<std::vector<ConstraintEntry>> cluster_primal_constraints(const Decomposition& dec,
                                                                     int c) {
  std::vector<std::vector<ConstraintEntry>> rows;
  const int m = dec.m(), mm = m * m, H = dec.H();
  if (m == 1) return rows;
  if (dec.glue_averages()) {
    const int p = H - 1;
    const double v = 1.0 / std::sqrt(2.0 * p);
    for (int dir = 0; dir < 2; ++dir)
      for (int ly = 0; ly < m - dir; ++ly)
        for (int lx = 0; lx < m - (1 - dir); ++lx) {
          const int si = c * mm + ly * m + lx, sj = dir == 0 ? si + 1 : si + m;
          std::vector<ConstraintEntry> row;
          for (int t = 1; t < H; ++t) {
            row.push_back({si, dir == 0 ? dec.local_node(H, t) : dec.local_node(t, H), v});
            row.push_back({sj, dir == 0 ? dec.local_node(0, t) : dec.local_node(t, 0), -v});
          }
          rows.push_back(std::move(row));
        }
  }
  if (dec.glue_corners()) {
    // Subdomain corners of the cluster: lattice points (lx, ly) in [0, m]^2.
    for (int ly = 0; ly <= m; ++ly)
      for (int lx = 0; lx <= m; ++lx) {
        std::vector<std::pair<int, int>> copies;  // (subdomain, dof)
        for (int dy = -1; dy <= 0; ++dy)
          for (int dx = -1; dx <= 0; ++dx) {
            const int sx = lx + dx, sy = ly + dy;
            if (sx < 0 || sy < 0 || sx >= m || sy >= m) continue;
            copies.emplace_back(c * mm + sy * m + sx, dec.local_node((lx - sx) * H, (ly - sy) * H));
          }
        if (copies.size() < 2) continue;
        for (const auto& r : orthonormal_complement(std::vector<double>(copies.size(), 1.0))) {
          std::vector<ConstraintEntry> row;
          for (size_t i = 0; i < copies.size(); ++i)
            row.push_back({copies[i].first, copies[i].second, r[i]});
          rows.push_back(std::move(row));
        }
      }
  }
  return rows;
}

}  // namespace htfeti
