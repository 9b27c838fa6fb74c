#include "htfeti/fem/element.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace htfeti {

namespace {

// Reference node coordinates of quad4 ([0,1]^2, the 2D built-ins' convention) and hex8 ([-1,1]^3).
constexpr double q4[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
constexpr double h8[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                             {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};

struct QuadPoint {
  Eigen::MatrixXd dN;  // n x dim physical gradients
  Eigen::VectorXd N;   // n shape values
  double w;            // weight x |det J|
};

// Shape values and reference gradients at a reference point.
void reference_shape(CellType t, const double* xi, Eigen::VectorXd& N, Eigen::MatrixXd& dN) {
  switch (t) {
    case CellType::tri3:
      N.resize(3), dN.resize(3, 2);
      N << 1 - xi[0] - xi[1], xi[0], xi[1];
      dN << -1, -1, 1, 0, 0, 1;
      return;
    case CellType::tet4:
      N.resize(4), dN.resize(4, 3);
      N << 1 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2];
      dN << -1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1;
      return;
    case CellType::quad4:
      N.resize(4), dN.resize(4, 2);
      for (int a = 0; a < 4; ++a) {
        const double sx = q4[a][0] ? xi[0] : 1 - xi[0], sy = q4[a][1] ? xi[1] : 1 - xi[1];
        N[a] = sx * sy;
        dN(a, 0) = (q4[a][0] ? 1.0 : -1.0) * sy;
        dN(a, 1) = (q4[a][1] ? 1.0 : -1.0) * sx;
      }
      return;
    case CellType::hex8:
      N.resize(8), dN.resize(8, 3);
      for (int a = 0; a < 8; ++a) {
        const double f0 = 1 + h8[a][0] * xi[0], f1 = 1 + h8[a][1] * xi[1],
                     f2 = 1 + h8[a][2] * xi[2];
        N[a] = f0 * f1 * f2 / 8;
        dN(a, 0) = h8[a][0] * f1 * f2 / 8;
        dN(a, 1) = f0 * h8[a][1] * f2 / 8;
        dN(a, 2) = f0 * f1 * h8[a][2] / 8;
      }
      return;
  }
}

// Gauss points in reference coordinates with weights.
void gauss_points(CellType t, std::vector<std::array<double, 4>>& pts) {
  pts.clear();
  switch (t) {
    case CellType::tri3:
      pts.push_back({1.0 / 3, 1.0 / 3, 0, 0.5});
      return;
    case CellType::tet4:
      pts.push_back({0.25, 0.25, 0.25, 1.0 / 6});
      return;
    case CellType::quad4: {
      const double g = 0.5 / std::sqrt(3.0);
      for (double a : {0.5 - g, 0.5 + g})
        for (double b : {0.5 - g, 0.5 + g}) pts.push_back({a, b, 0, 0.25});
      return;
    }
    case CellType::hex8: {
      const double g = 1.0 / std::sqrt(3.0);
      for (double a : {-g, g})
        for (double b : {-g, g})
          for (double c : {-g, g}) pts.push_back({a, b, c, 1.0});
      return;
    }
  }
}

std::vector<QuadPoint> quadrature(CellType t, const double* x) {
  const int n = cell_nodes(t), dim = cell_dimension(t);
  std::vector<std::array<double, 4>> pts;
  gauss_points(t, pts);
  std::vector<QuadPoint> out;
  Eigen::MatrixXd X(n, dim);
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < dim; ++d) X(a, d) = x[3 * a + d];
  for (const auto& p : pts) {
    QuadPoint q;
    Eigen::MatrixXd dNr;
    reference_shape(t, p.data(), q.N, dNr);
    const Eigen::MatrixXd J = X.transpose() * dNr;  // dim x dim: dx/dxi
    const double det = J.determinant();
    if (!(std::abs(det) > 0))
      throw std::invalid_argument("a " + to_string(t) + " element has zero or invalid volume");
    q.dN = dNr * J.inverse();
    q.w = p[3] * std::abs(det);
    out.push_back(std::move(q));
  }
  return out;
}

Eigen::MatrixXd strain_matrix(int dim, const Eigen::MatrixXd& dN) {
  const int n = static_cast<int>(dN.rows());
  Eigen::MatrixXd B;
  if (dim == 2) {
    B = Eigen::MatrixXd::Zero(3, 2 * n);
    for (int a = 0; a < n; ++a) {
      B(0, 2 * a) = dN(a, 0);
      B(1, 2 * a + 1) = dN(a, 1);
      B(2, 2 * a) = dN(a, 1);
      B(2, 2 * a + 1) = dN(a, 0);
    }
  } else {
    B = Eigen::MatrixXd::Zero(6, 3 * n);
    for (int a = 0; a < n; ++a) {
      B(0, 3 * a) = dN(a, 0);
      B(1, 3 * a + 1) = dN(a, 1);
      B(2, 3 * a + 2) = dN(a, 2);
      B(3, 3 * a) = dN(a, 1);
      B(3, 3 * a + 1) = dN(a, 0);
      B(4, 3 * a + 1) = dN(a, 2);
      B(4, 3 * a + 2) = dN(a, 1);
      B(5, 3 * a) = dN(a, 2);
      B(5, 3 * a + 2) = dN(a, 0);
    }
  }
  return B;
}

// The 3D cells (tet4, hex8) with fixed sizes: N nodes, the reference gradients and weights of
// their Gauss points tabulated once, Jacobians as 3 x 3 matrices on the stack. These carry the
// assembly of every 3D subdomain that is not a generated grid (a METIS split computes one element
// matrix per cell, twice: for K_i and for the energy check), where the general path above spent
// more time allocating its small dynamic matrices than computing (docs/performance.md, "Element
// matrices"). The 2D cells keep the general path, on which Tables 2 and 3 were verified.
template <int N>
struct Rule3 {
  int points = 0;
  double weight[8];
  double N_[8][N];
  double dN[8][N][3];
};

template <int N>
Rule3<N> make_rule3(CellType t) {
  Rule3<N> r;
  std::vector<std::array<double, 4>> pts;
  gauss_points(t, pts);
  r.points = static_cast<int>(pts.size());
  for (int q = 0; q < r.points; ++q) {
    Eigen::VectorXd Nv;
    Eigen::MatrixXd dNr;
    reference_shape(t, pts[q].data(), Nv, dNr);
    r.weight[q] = pts[q][3];
    for (int a = 0; a < N; ++a) {
      r.N_[q][a] = Nv[a];
      for (int k = 0; k < 3; ++k) r.dN[q][a][k] = dNr(a, k);
    }
  }
  return r;
}

template <int N>
const Rule3<N>& rule3() {
  static const Rule3<N> r = make_rule3<N>(N == 8 ? CellType::hex8 : CellType::tet4);
  return r;
}

// At Gauss point q of the cell with coordinates x: the physical gradients g (N x 3) and the
// weight times |det J|. Throws on a zero or non-finite Jacobian, as quadrature() does.
template <int N>
double gradients3(const Rule3<N>& r, int q, const double* x, double (*g)[3], CellType t) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();  // J(i, k) = sum_a x_a,i dN_a / dxi_k
  for (int a = 0; a < N; ++a)
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) J(i, k) += x[3 * a + i] * r.dN[q][a][k];
  const double det = J.determinant();
  if (!(std::abs(det) > 0))
    throw std::invalid_argument("a " + to_string(t) + " element has zero or invalid volume");
  if (g) {
    const Eigen::Matrix3d Ji = J.inverse();
    for (int a = 0; a < N; ++a)
      for (int j = 0; j < 3; ++j)
        g[a][j] = r.dN[q][a][0] * Ji(0, j) + r.dN[q][a][1] * Ji(1, j) + r.dN[q][a][2] * Ji(2, j);
  }
  return r.weight[q] * std::abs(det);
}

// Isotropic elasticity, K_ab(i, j) = sum_q w (lambda g_a,i g_b,j + mu g_a,j g_b,i
// + mu (g_a . g_b) delta_ij): B^T D B written out (exactly symmetric).
template <int N>
Eigen::MatrixXd elasticity3(CellType t, const double* x, double lambda, double mu) {
  const auto& r = rule3<N>();
  Eigen::Matrix<double, 3 * N, 3 * N> K = Eigen::Matrix<double, 3 * N, 3 * N>::Zero();
  double g[N][3];
  for (int q = 0; q < r.points; ++q) {
    const double w = gradients3<N>(r, q, x, g, t);
    for (int a = 0; a < N; ++a)
      for (int b = a; b < N; ++b) {
        const double gg = g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            K(3 * a + i, 3 * b + j) += w * (lambda * (g[a][i] * g[b][j]) +
                                            mu * (g[a][j] * g[b][i]) + (i == j ? mu * gg : 0.0));
      }
  }
  for (int a = 0; a < N; ++a)
    for (int b = a + 1; b < N; ++b)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) K(3 * b + j, 3 * a + i) = K(3 * a + i, 3 * b + j);
  return K;
}

template <int N>
Eigen::MatrixXd laplace3(CellType t, const double* x) {
  const auto& r = rule3<N>();
  Eigen::Matrix<double, N, N> K = Eigen::Matrix<double, N, N>::Zero();
  double g[N][3];
  for (int q = 0; q < r.points; ++q) {
    const double w = gradients3<N>(r, q, x, g, t);
    for (int a = 0; a < N; ++a)
      for (int b = a; b < N; ++b)
        K(a, b) += w * (g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2]);
  }
  for (int a = 0; a < N; ++a)
    for (int b = a + 1; b < N; ++b) K(b, a) = K(a, b);
  return K;
}

template <int N>
double measure3(CellType t, const double* x) {
  const auto& r = rule3<N>();
  double s = 0;
  for (int q = 0; q < r.points; ++q) s += gradients3<N>(r, q, x, nullptr, t);
  return s;
}

template <int N>
Eigen::VectorXd shape_integrals3(CellType t, const double* x) {
  const auto& r = rule3<N>();
  Eigen::VectorXd v = Eigen::VectorXd::Zero(N);
  for (int q = 0; q < r.points; ++q) {
    const double w = gradients3<N>(r, q, x, nullptr, t);
    for (int a = 0; a < N; ++a) v[a] += w * r.N_[q][a];
  }
  return v;
}

}  // namespace

Eigen::MatrixXd elasticity_matrix(int dim, const Material& m) {
  const double E = m.young, nu = m.poisson;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  if (dim == 2) {
    Eigen::MatrixXd D(3, 3);
    D << lambda + 2 * mu, lambda, 0, lambda, lambda + 2 * mu, 0, 0, 0, mu;
    return D;
  }
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6, 6);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) = lambda + 2 * mu;
    D(3 + i, 3 + i) = mu;
  }
  return D;
}

Eigen::MatrixXd laplace_stiffness(CellType t, const double* x) {
  if (t == CellType::hex8) return laplace3<8>(t, x);
  if (t == CellType::tet4) return laplace3<4>(t, x);
  const int n = cell_nodes(t);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
  for (const auto& q : quadrature(t, x)) K.noalias() += q.w * q.dN * q.dN.transpose();
  return K;
}

Eigen::MatrixXd elasticity_stiffness(CellType t, const double* x, const Material& m) {
  if (t == CellType::hex8 || t == CellType::tet4) {
    const double E = m.young, nu = m.poisson;
    const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
    return t == CellType::hex8 ? elasticity3<8>(t, x, lambda, mu)
                               : elasticity3<4>(t, x, lambda, mu);
  }
  const int n = cell_nodes(t), dim = cell_dimension(t);
  const Eigen::MatrixXd D = elasticity_matrix(dim, m);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(dim * n, dim * n);
  for (const auto& q : quadrature(t, x)) {
    const Eigen::MatrixXd B = strain_matrix(dim, q.dN);
    K.noalias() += q.w * B.transpose() * D * B;
  }
  return K;
}

Eigen::VectorXd shape_integrals(CellType t, const double* x) {
  if (t == CellType::hex8) return shape_integrals3<8>(t, x);
  if (t == CellType::tet4) return shape_integrals3<4>(t, x);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(cell_nodes(t));
  for (const auto& q : quadrature(t, x)) v += q.w * q.N;
  return v;
}

double cell_measure(CellType t, const double* x) {
  if (t == CellType::hex8) return measure3<8>(t, x);
  if (t == CellType::tet4) return measure3<4>(t, x);
  double s = 0;
  for (const auto& q : quadrature(t, x)) s += q.w;
  return s;
}

std::array<double, 3> cell_centroid(CellType t, const double* x) {
  std::array<double, 3> c{0, 0, 0};
  const int n = cell_nodes(t);
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < 3; ++d) c[d] += x[3 * a + d] / n;
  return c;
}

Eigen::MatrixXd strain_matrix_at_centroid(CellType t, const double* x) {
  const int n = cell_nodes(t), dim = cell_dimension(t);
  double xi[3] = {0, 0, 0};
  if (t == CellType::tri3) xi[0] = xi[1] = 1.0 / 3;
  if (t == CellType::tet4) xi[0] = xi[1] = xi[2] = 0.25;
  if (t == CellType::quad4) xi[0] = xi[1] = 0.5;
  Eigen::VectorXd N;
  Eigen::MatrixXd dNr;
  reference_shape(t, xi, N, dNr);
  Eigen::MatrixXd X(n, dim);
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < dim; ++d) X(a, d) = x[3 * a + d];
  const Eigen::MatrixXd J = X.transpose() * dNr;
  return strain_matrix(dim, dNr * J.inverse());
}

double von_mises(int dim, const Eigen::VectorXd& s, double nu) {
  double sxx, syy, szz, sxy, syz, szx;
  if (dim == 2) {
    sxx = s[0], syy = s[1], sxy = s[2], szz = nu * (sxx + syy), syz = szx = 0;
  } else {
    sxx = s[0], syy = s[1], szz = s[2], sxy = s[3], syz = s[4], szx = s[5];
  }
  return std::sqrt(
      0.5 * ((sxx - syy) * (sxx - syy) + (syy - szz) * (syy - szz) + (szz - sxx) * (szz - sxx)) +
      3 * (sxy * sxy + syz * syz + szx * szx));
}

double facet_measure(int dim, int n, const double* x) {
  auto sub = [&](int a, int b, double* v) {
    for (int d = 0; d < 3; ++d) v[d] = x[3 * a + d] - x[3 * b + d];
  };
  auto cross_norm = [](const double* u, const double* v) {
    const double c0 = u[1] * v[2] - u[2] * v[1], c1 = u[2] * v[0] - u[0] * v[2],
                 c2 = u[0] * v[1] - u[1] * v[0];
    return std::sqrt(c0 * c0 + c1 * c1 + c2 * c2);
  };
  double u[3], v[3];
  if (n == 2) {
    sub(1, 0, u);
    return std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  }
  if (n == 3) {
    sub(1, 0, u), sub(2, 0, v);
    return 0.5 * cross_norm(u, v);
  }
  // quad: two triangles (exact for planar quads)
  sub(1, 0, u), sub(2, 0, v);
  double a = 0.5 * cross_norm(u, v);
  sub(2, 0, u), sub(3, 0, v);
  return a + 0.5 * cross_norm(u, v);
  (void)dim;
}

bool cell_is_valid(CellType t, const double* x) {
  const int n = cell_nodes(t), dim = cell_dimension(t);
  // The size of the cell: its largest coordinate extent.
  double h = 0;
  for (int d = 0; d < dim; ++d) {
    double lo = x[d], hi = x[d];
    for (int a = 1; a < n; ++a) lo = std::min(lo, x[3 * a + d]), hi = std::max(hi, x[3 * a + d]);
    h = std::max(h, hi - lo);
  }
  if (!(h > 0) || !std::isfinite(h)) return false;
  Eigen::MatrixXd X(n, dim);
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < dim; ++d) X(a, d) = x[3 * a + d];
  // det J at the corners of the reference cell (constant for simplices): an inverted or
  // self-intersecting (bow-tie) quad or hex changes sign there; a degenerate cell is 0.
  std::vector<std::array<double, 3>> corners;
  if (t == CellType::quad4)
    for (const auto& c : q4) corners.push_back({c[0], c[1], 0});
  else if (t == CellType::hex8)
    for (const auto& c : h8) corners.push_back({c[0], c[1], c[2]});
  else
    corners.push_back({0.25, 0.25, 0.25});
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  Eigen::VectorXd N;
  Eigen::MatrixXd dN;
  for (const auto& c : corners) {
    reference_shape(t, c.data(), N, dN);
    const double det = (X.transpose() * dN).determinant();
    lo = std::min(lo, det), hi = std::max(hi, det);
  }
  const double tiny = 1e-12 * std::pow(h, dim);
  return (lo > tiny && hi > tiny) || (lo < -tiny && hi < -tiny);
}

}  // namespace htfeti
