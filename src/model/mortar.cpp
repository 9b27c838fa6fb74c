// Mortar rows (mortar.hpp): the contact search, the intersections of slave and master facets
// and the Gauss rules on them.
#include "htfeti/model/mortar.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

namespace htfeti {

namespace {

using V3 = std::array<double, 3>;
using P2 = std::array<double, 2>;

V3 point(const std::vector<double>& x, int i) {
  const size_t k = 3 * static_cast<size_t>(i);
  return {x[k], x[k + 1], x[k + 2]};
}
V3 sub(const V3& a, const V3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const V3& a) { return std::sqrt(dot(a, a)); }

// The measure of a facet (length, or area: a quad as two triangles).
double facet_measure(const std::vector<double>& x, const int* f, int fn) {
  if (fn == 2) return norm(sub(point(x, f[1]), point(x, f[0])));
  const V3 a = point(x, f[0]);
  double m = 0.5 * norm(cross(sub(point(x, f[1]), a), sub(point(x, f[2]), a)));
  if (fn == 4) m += 0.5 * norm(cross(sub(point(x, f[2]), a), sub(point(x, f[3]), a)));
  return m;
}

// Gauss-Legendre on [0, 1], 3 points (exact to degree 5).
constexpr double kG3x[3] = {0.11270166537925831, 0.5, 0.88729833462074169};
constexpr double kG3w[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
// Dunavant's 7-point rule on a triangle (exact to degree 5): barycentric points, weights summing
// to 1.
constexpr double kT7[7][4] = {
    {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.225},
    {0.059715871789770, 0.470142064105115, 0.470142064105115, 0.132394152788506},
    {0.470142064105115, 0.059715871789770, 0.470142064105115, 0.132394152788506},
    {0.470142064105115, 0.470142064105115, 0.059715871789770, 0.132394152788506},
    {0.797426985353087, 0.101286507323456, 0.101286507323456, 0.125939180544827},
    {0.101286507323456, 0.797426985353087, 0.101286507323456, 0.125939180544827},
    {0.101286507323456, 0.101286507323456, 0.797426985353087, 0.125939180544827}};

double signed_area(const std::vector<P2>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const P2& u = p[i];
    const P2& v = p[(i + 1) % p.size()];
    a += u[0] * v[1] - v[0] * u[1];
  }
  return 0.5 * a;
}

// Sutherland-Hodgman: the part of `subject` inside the convex counterclockwise polygon `clip`.
std::vector<P2> clip_polygon(std::vector<P2> subject, const std::vector<P2>& clip) {
  for (size_t e = 0; e < clip.size() && !subject.empty(); ++e) {
    const P2 a = clip[e], b = clip[(e + 1) % clip.size()];
    auto side = [&](const P2& p) {
      return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    };
    std::vector<P2> out;
    for (size_t i = 0; i < subject.size(); ++i) {
      const P2 p = subject[i], q = subject[(i + 1) % subject.size()];
      const double sp = side(p), sq = side(q);
      if (sp >= 0) out.push_back(p);
      if ((sp >= 0) != (sq >= 0)) {
        const double t = sp / (sp - sq);
        out.push_back({p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])});
      }
    }
    subject = std::move(out);
  }
  return subject;
}

// The shape functions of a facet (3 or 4 nodes, projected to the plane as `v`, in the facet's
// own node order) at the plane point p: barycentric for a triangle, the inverse bilinear map
// (Newton from the centre) for a quad.
void plane_shape(const std::vector<P2>& v, const P2& p, double* N) {
  if (v.size() == 3) {
    const double x1 = v[1][0] - v[0][0], y1 = v[1][1] - v[0][1];
    const double x2 = v[2][0] - v[0][0], y2 = v[2][1] - v[0][1];
    const double det = x1 * y2 - x2 * y1;
    const double px = p[0] - v[0][0], py = p[1] - v[0][1];
    const double l1 = (px * y2 - x2 * py) / det, l2 = (x1 * py - px * y1) / det;
    N[0] = 1 - l1 - l2, N[1] = l1, N[2] = l2;
    return;
  }
  double xi = 0, eta = 0;
  for (int it = 0; it < 30; ++it) {
    const double n[4] = {0.25 * (1 - xi) * (1 - eta), 0.25 * (1 + xi) * (1 - eta),
                         0.25 * (1 + xi) * (1 + eta), 0.25 * (1 - xi) * (1 + eta)};
    const double dxi[4] = {-0.25 * (1 - eta), 0.25 * (1 - eta), 0.25 * (1 + eta),
                           -0.25 * (1 + eta)};
    const double deta[4] = {-0.25 * (1 - xi), -0.25 * (1 + xi), 0.25 * (1 + xi), 0.25 * (1 - xi)};
    double rx = -p[0], ry = -p[1], a = 0, b = 0, c = 0, d = 0;
    for (int k = 0; k < 4; ++k) {
      rx += n[k] * v[k][0], ry += n[k] * v[k][1];
      a += dxi[k] * v[k][0], b += deta[k] * v[k][0];
      c += dxi[k] * v[k][1], d += deta[k] * v[k][1];
    }
    const double det = a * d - b * c;
    const double dx = (d * rx - b * ry) / det, dy = (a * ry - c * rx) / det;
    xi -= dx, eta -= dy;
    if (std::abs(dx) + std::abs(dy) < 1e-15) break;
  }
  xi = std::clamp(xi, -1.0, 1.0), eta = std::clamp(eta, -1.0, 1.0);
  N[0] = 0.25 * (1 - xi) * (1 - eta), N[1] = 0.25 * (1 + xi) * (1 - eta);
  N[2] = 0.25 * (1 + xi) * (1 + eta), N[3] = 0.25 * (1 - xi) * (1 + eta);
}

// Uniform bins over the master facets' bounding boxes.
class Bins {
 public:
  Bins(const std::vector<double>& x, const ContactSurface& s, double min_cell) {
    const int fn = s.facet_nodes, nf = s.num_facets();
    lo_.resize(nf), hi_.resize(nf);
    double cell = min_cell;
    for (int f = 0; f < nf; ++f) {
      V3 lo = point(x, s.nodes[static_cast<size_t>(f) * fn]), hi = lo;
      for (int a = 1; a < fn; ++a) {
        const V3 p = point(x, s.nodes[static_cast<size_t>(f) * fn + a]);
        for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], p[d]), hi[d] = std::max(hi[d], p[d]);
      }
      lo_[f] = lo, hi_[f] = hi;
      for (int d = 0; d < 3; ++d) cell = std::max(cell, hi[d] - lo[d]);
    }
    cell_ = cell > 0 ? cell : 1.0;
    for (int f = 0; f < nf; ++f) {
      const auto a = index(lo_[f]), b = index(hi_[f]);
      for (long long i = a[0]; i <= b[0]; ++i)
        for (long long j = a[1]; j <= b[1]; ++j)
          for (long long k = a[2]; k <= b[2]; ++k) bins_[key(i, j, k)].push_back(f);
    }
  }
  /// Master facets whose bins meet the box [lo - r, hi + r], sorted.
  void query(V3 lo, V3 hi, double r, std::vector<int>& out) const {
    out.clear();
    for (int d = 0; d < 3; ++d) lo[d] -= r, hi[d] += r;
    const auto a = index(lo), b = index(hi);
    for (long long i = a[0]; i <= b[0]; ++i)
      for (long long j = a[1]; j <= b[1]; ++j)
        for (long long k = a[2]; k <= b[2]; ++k) {
          auto it = bins_.find(key(i, j, k));
          if (it == bins_.end()) continue;
          for (int f : it->second) {
            bool meets = true;
            for (int d = 0; d < 3; ++d) meets = meets && lo_[f][d] <= hi[d] && hi_[f][d] >= lo[d];
            if (meets) out.push_back(f);
          }
        }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }

 private:
  std::array<long long, 3> index(const V3& p) const {
    return {static_cast<long long>(std::floor(p[0] / cell_)),
            static_cast<long long>(std::floor(p[1] / cell_)),
            static_cast<long long>(std::floor(p[2] / cell_))};
  }
  static long long key(long long i, long long j, long long k) {
    return (i * 73856093LL) ^ (j * 19349663LL) ^ (k * 83492791LL);
  }
  double cell_ = 1;
  std::vector<V3> lo_, hi_;
  std::unordered_map<long long, std::vector<int>> bins_;
};

// One Gauss point of a slave facet's overlaps with master facets: weight, the slave facet's
// shape values, the master facet and its shape values, the gap vector x_m - x_s.
struct GaussPoint {
  double w;
  double phi[4];
  int master;
  double N[4];
  V3 dx;
};

// The dual basis of a slave facet (Wohlmuth's biorthogonal multipliers): theta_a = sum_b A_ab
// phi_b with int theta_a phi_b = delta_ab int phi_b over the facet, so A = D_e M_e^-1, M_e the
// facet's mass matrix and D_e = diag(int phi_b). A segment: A = [[2, -1], [-1, 2]] (theta_a =
// 3 phi_a - 1); a triangle: theta_a = 4 phi_a - 1; a quad: M_e by the 7-point rule on the
// facet's fan of triangles (as the overlaps are integrated). `S`: the facet's nodes in its plane.
void dual_coefficients(int sf, const std::vector<P2>& S, double A[4][4]) {
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) A[a][b] = 0.0;
  if (sf == 2 || sf == 3) {
    const double c = sf == 2 ? 3.0 : 4.0;
    for (int a = 0; a < sf; ++a)
      for (int b = 0; b < sf; ++b) A[a][b] = (a == b ? c : 0.0) - 1.0;
    return;
  }
  Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
  P2 cen{0, 0};
  for (const auto& p : S) cen[0] += p[0] / 4, cen[1] += p[1] / 4;
  for (int e = 0; e < 4; ++e) {
    const P2& p1 = S[e];
    const P2& p2 = S[(e + 1) % 4];
    const double At =
        std::abs(0.5 * ((p1[0] - cen[0]) * (p2[1] - cen[1]) - (p2[0] - cen[0]) * (p1[1] - cen[1])));
    for (const auto& r : kT7) {
      const P2 p{r[0] * cen[0] + r[1] * p1[0] + r[2] * p2[0],
                 r[0] * cen[1] + r[1] * p1[1] + r[2] * p2[1]};
      double phi[4];
      plane_shape(S, p, phi);
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) M(a, b) += At * r[3] * phi[a] * phi[b];
    }
  }
  const Eigen::Matrix4d Minv = M.inverse();
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) A[a][b] = M.row(a).sum() * Minv(a, b);
}

// Per slave node: its D and M entries and weighted gap, accumulated facet by facet.
struct Accumulator {
  std::vector<std::vector<std::pair<int, double>>> entries;  // per slave node (index), unmerged
  std::vector<double> gap;
  // One Gauss point: the test functions theta (the slave facet's phi or its dual), slave
  // nodes/shape values phi, master nodes/shape values N.
  void add(const GaussPoint& q, const double* theta, const int* sn, const int* sl, int ns,
           const int* mn, int nm, const std::vector<V3>& normal) {
    for (int a = 0; a < ns; ++a) {
      const int i = sl[a];
      const double wa = q.w * theta[a];
      if (wa == 0.0) continue;
      for (int b = 0; b < ns; ++b) entries[i].push_back({sn[b], wa * q.phi[b]});
      for (int b = 0; b < nm; ++b) entries[i].push_back({mn[b], -wa * q.N[b]});
      gap[i] += wa * dot(normal[i], q.dx);
    }
  }
};

}  // namespace

double largest_facet_diameter(const std::vector<double>& x, const ContactSurface& s) {
  double d = 0;
  const int fn = s.facet_nodes;
  for (int f = 0; f < s.num_facets(); ++f)
    for (int a = 0; a < fn; ++a)
      for (int b = a + 1; b < fn; ++b)
        d = std::max(d, norm(sub(point(x, s.nodes[static_cast<size_t>(f) * fn + a]),
                                 point(x, s.nodes[static_cast<size_t>(f) * fn + b]))));
  return d;
}

std::vector<MortarRow> mortar_rows(int dim, const std::vector<double>& x,
                                   const ContactSurface& slave, const ContactSurface& master,
                                   double delta, MortarBasis basis) {
  const int sf = slave.facet_nodes, mf = master.facet_nodes;
  if ((dim == 2 && (sf != 2 || mf != 2)) || (dim == 3 && (sf < 3 || mf < 3)))
    throw std::invalid_argument("mortar_rows: facets do not fit the dimension");
  // Slave nodes (sorted), their normals and measures.
  std::vector<int> snodes(slave.nodes.begin(), slave.nodes.end());
  std::sort(snodes.begin(), snodes.end());
  snodes.erase(std::unique(snodes.begin(), snodes.end()), snodes.end());
  auto slot = [&](int g) {
    return static_cast<int>(std::lower_bound(snodes.begin(), snodes.end(), g) - snodes.begin());
  };
  const int ns = static_cast<int>(snodes.size());
  std::vector<V3> normal(ns, V3{0, 0, 0});
  std::vector<double> measure(ns, 0.0);
  for (int f = 0; f < slave.num_facets(); ++f) {
    const int* fnodes = slave.nodes.data() + static_cast<size_t>(f) * sf;
    const double m = facet_measure(x, fnodes, sf);
    for (int a = 0; a < sf; ++a) {
      const int i = slot(fnodes[a]);
      for (int d = 0; d < 3; ++d) normal[i][d] += m * slave.normals[f][d];
      measure[i] += m / sf;
    }
  }
  for (auto& n : normal) {
    const double l = norm(n);
    if (l > 0)
      for (double& v : n) v /= l;
  }
  Accumulator acc;
  acc.entries.assign(ns, {});
  acc.gap.assign(ns, 0.0);
  const Bins bins(x, master, delta);
  std::vector<int> cand;
  std::vector<GaussPoint> points;  // of one slave facet
  for (int f = 0; f < slave.num_facets(); ++f) {
    const int* fs = slave.nodes.data() + static_cast<size_t>(f) * sf;
    int sl[4];
    V3 xs[4], lo = point(x, fs[0]), hi = lo;
    for (int a = 0; a < sf; ++a) {
      sl[a] = slot(fs[a]);
      xs[a] = point(x, fs[a]);
      for (int d = 0; d < 3; ++d)
        lo[d] = std::min(lo[d], xs[a][d]), hi[d] = std::max(hi[d], xs[a][d]);
    }
    const V3& nf = slave.normals[f];
    bins.query(lo, hi, delta, cand);
    // The slave facet's plane: centre, normal nf, in-plane axes e1, e2 (3D).
    V3 c{0, 0, 0}, e1{0, 0, 0}, e2{0, 0, 0};
    for (int a = 0; a < sf; ++a)
      for (int d = 0; d < 3; ++d) c[d] += xs[a][d] / sf;
    std::vector<P2> S;
    if (dim == 3) {
      e1 = sub(xs[1], xs[0]);
      const double t = dot(e1, nf);
      for (int d = 0; d < 3; ++d) e1[d] -= t * nf[d];
      const double l = norm(e1);
      for (double& v : e1) v /= l;
      e2 = cross(nf, e1);
      for (int a = 0; a < sf; ++a) S.push_back({dot(sub(xs[a], c), e1), dot(sub(xs[a], c), e2)});
    }
    std::vector<P2> Sccw = S;
    if (dim == 3 && signed_area(Sccw) < 0) std::reverse(Sccw.begin(), Sccw.end());
    points.clear();
    for (int g : cand) {
      const int* fm = master.nodes.data() + static_cast<size_t>(g) * mf;
      if (dot(nf, master.normals[g]) >= 0) continue;  // not facing each other
      V3 xm[4];
      double dmin = INFINITY, dmax = -INFINITY;
      for (int b = 0; b < mf; ++b) {
        xm[b] = point(x, fm[b]);
        const double dist = dot(sub(xm[b], c), nf);
        dmin = std::min(dmin, dist), dmax = std::max(dmax, dist);
      }
      if (dmin > delta || dmax < -delta) continue;
      if (dim == 2) {
        const V3 t = sub(xs[1], xs[0]);
        const double L = norm(t);
        const double ta = dot(sub(xm[0], xs[0]), t) / (L * L);
        const double tb = dot(sub(xm[1], xs[0]), t) / (L * L);
        if (std::abs(tb - ta) < 1e-12) continue;
        const double a = std::max(0.0, std::min(ta, tb)), b = std::min(1.0, std::max(ta, tb));
        if (b - a <= 1e-12) continue;
        for (int q = 0; q < 3; ++q) {
          const double ts = a + (b - a) * kG3x[q], w = (b - a) * L * kG3w[q];
          const double s = (ts - ta) / (tb - ta);
          const double phi[2] = {1 - ts, ts}, N[2] = {1 - s, s};
          V3 dx;
          for (int d = 0; d < 3; ++d)
            dx[d] = (1 - s) * xm[0][d] + s * xm[1][d] - ((1 - ts) * xs[0][d] + ts * xs[1][d]);
          points.push_back({w, {phi[0], phi[1], 0, 0}, g, {N[0], N[1], 0, 0}, dx});
        }
        continue;
      }
      std::vector<P2> M;
      for (int b = 0; b < mf; ++b) M.push_back({dot(sub(xm[b], c), e1), dot(sub(xm[b], c), e2)});
      std::vector<P2> Mccw = M;
      if (signed_area(Mccw) < 0) std::reverse(Mccw.begin(), Mccw.end());
      const std::vector<P2> poly = clip_polygon(Mccw, Sccw);
      if (poly.size() < 3 || signed_area(poly) <= 1e-12 * std::abs(signed_area(Sccw))) continue;
      P2 cen{0, 0};
      for (const auto& p : poly) cen[0] += p[0] / poly.size(), cen[1] += p[1] / poly.size();
      for (size_t e = 0; e < poly.size(); ++e) {
        const P2& p1 = poly[e];
        const P2& p2 = poly[(e + 1) % poly.size()];
        const double At =
            0.5 * ((p1[0] - cen[0]) * (p2[1] - cen[1]) - (p2[0] - cen[0]) * (p1[1] - cen[1]));
        if (At <= 0) continue;
        for (const auto& r : kT7) {
          const P2 p{r[0] * cen[0] + r[1] * p1[0] + r[2] * p2[0],
                     r[0] * cen[1] + r[1] * p1[1] + r[2] * p2[1]};
          double phi[4], N[4];
          plane_shape(S, p, phi);
          plane_shape(M, p, N);
          V3 dx{0, 0, 0};
          for (int d = 0; d < 3; ++d) {
            for (int a = 0; a < sf; ++a) dx[d] -= phi[a] * xs[a][d];
            for (int b = 0; b < mf; ++b) dx[d] += N[b] * xm[b][d];
          }
          GaussPoint q{At * r[3], {0, 0, 0, 0}, g, {0, 0, 0, 0}, dx};
          std::copy(phi, phi + sf, q.phi);
          std::copy(N, N + mf, q.N);
          points.push_back(q);
        }
      }
    }
    // The test functions: the dual basis where the master covers the whole facet, else (at the
    // master surface's edge, where the dual weights of a partly covered facet can vanish or turn
    // negative) the standard one. The coverage: the overlaps' total measure against the facet's.
    double covered = 0.0;
    for (const auto& q : points) covered += q.w;
    const double whole = dim == 2 ? norm(sub(xs[1], xs[0])) : std::abs(signed_area(S));
    bool dual = basis == MortarBasis::dual && covered >= (1.0 - 1e-9) * whole;
    double A[4][4];
    if (dual) {
      // Covered whole, each node's dual weight int theta_a equals its standard one int phi_a;
      // where they differ the overlaps are not one cover of the facet (master facets whose
      // projections overlap around a gap), and the facet keeps the standard functions.
      dual_coefficients(sf, S, A);
      for (int a = 0; a < sf && dual; ++a) {
        double d = 0.0, st = 0.0;
        for (const auto& q : points) {
          st += q.w * q.phi[a];
          for (int b = 0; b < sf; ++b) d += q.w * A[a][b] * q.phi[b];
        }
        dual = std::abs(d - st) <= 1e-3 * whole;  // (quads: the rule on other triangles)
      }
    }
    for (const auto& q : points) {
      double theta[4];
      for (int a = 0; a < sf; ++a) {
        theta[a] = dual ? 0.0 : q.phi[a];
        if (dual)
          for (int b = 0; b < sf; ++b) theta[a] += A[a][b] * q.phi[b];
      }
      acc.add(q, theta, fs, sl, sf, master.nodes.data() + static_cast<size_t>(q.master) * mf, mf,
              normal);
    }
  }
  // Merge each slave node's entries by node, in a fixed order.
  std::vector<MortarRow> rows;
  for (int i = 0; i < ns; ++i) {
    auto& e = acc.entries[i];
    if (e.empty()) continue;
    std::stable_sort(e.begin(), e.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    MortarRow r;
    r.slave_node = snodes[i];
    r.normal = normal[i];
    r.area = measure[i];
    for (size_t k = 0; k < e.size();) {
      double v = 0;
      size_t j = k;
      for (; j < e.size() && e[j].first == e[k].first; ++j) v += e[j].second;
      r.entries.push_back({e[k].first, v});
      if (std::binary_search(snodes.begin(), snodes.end(), e[k].first)) r.weight += v;  // D_ij
      k = j;
    }
    if (!(r.weight > 1e-10 * measure[i])) continue;
    r.gap = acc.gap[i] / r.weight;
    rows.push_back(std::move(r));
  }
  return rows;
}

}  // namespace htfeti
