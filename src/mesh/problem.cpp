#include "htfeti/mesh/problem.hpp"

#include <cmath>
#include <stdexcept>

namespace htfeti {

ProblemKind parse_problem(const std::string& name) {
  return parse_name(kProblemNames, name, "problem");
}

std::string to_string(ProblemKind value) { return name_of(kProblemNames, value); }

ElementKind parse_element(const std::string& name) {
  return parse_name(kElementNames, name, "element");
}

std::string to_string(ElementKind value) { return name_of(kElementNames, value); }

double Problem::load(double x, double y) const {
  if (kind == ProblemKind::poisson2d) return 1.0;
  if (x < 1.0) return y > 0.75 ? -3.0 : 0.0;
  return y < 0.25 ? -1.0 : 0.0;
}

bool Problem::dirichlet(int q, int gx, int gy, int n) const {
  switch (kind) {
    case ProblemKind::poisson2d:
      return gx == 0 || gy == 0 || gx == n || gy == n;
    case ProblemKind::membranes:
      return q == 0 && gx == 0;
    case ProblemKind::membranes_coercive:
      return (q == 0 && gx == 0) || (q == 1 && gx == n);
  }
  return false;
}

namespace {
// Reference coordinates of the square's nodes, in the order of the header.
constexpr double node_x[4] = {0, 1, 1, 0};
constexpr double node_y[4] = {0, 0, 1, 1};
// P1 split: triangles (0,1,2) and (0,2,3), both with the diagonal 0-2.
constexpr int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};

// Stiffness of a linear triangle on the unit reference square's nodes: area * grad_i . grad_j.
void add_triangle(const int* t, std::array<std::array<double, 4>, 4>& k) {
  const double x1 = node_x[t[0]], y1 = node_y[t[0]], x2 = node_x[t[1]], y2 = node_y[t[1]],
               x3 = node_x[t[2]], y3 = node_y[t[2]];
  const double det = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1);
  const double bx[3] = {y2 - y3, y3 - y1, y1 - y2};  // det * d(phi_i)/dx
  const double by[3] = {x3 - x2, x1 - x3, x2 - x1};  // det * d(phi_i)/dy
  const double area = 0.5 * det;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      k[t[a]][t[b]] += area * (bx[a] * bx[b] + by[a] * by[b]) / (det * det);
}
}  // namespace

std::array<std::array<double, 4>, 4> square_stiffness(ElementKind element) {
  std::array<std::array<double, 4>, 4> k{};
  if (element == ElementKind::p1) {
    add_triangle(tri[0], k);
    add_triangle(tri[1], k);
    return k;
  }
  // Q1 by 2x2 Gauss quadrature (exact for the bilinear gradients' products).
  const double g = 0.5 / std::sqrt(3.0);
  const double pts[2] = {0.5 - g, 0.5 + g};
  for (double xi : pts)
    for (double eta : pts) {
      double dx[4], dy[4];
      for (int a = 0; a < 4; ++a) {
        const double sx = node_x[a] ? xi : 1 - xi, sy = node_y[a] ? eta : 1 - eta;
        dx[a] = (node_x[a] ? 1.0 : -1.0) * sy;
        dy[a] = (node_y[a] ? 1.0 : -1.0) * sx;
      }
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) k[a][b] += 0.25 * (dx[a] * dx[b] + dy[a] * dy[b]);
    }
  return k;
}

std::array<double, 4> square_load(const Problem& problem, ElementKind element, double x0, double y0,
                                  double h) {
  std::array<double, 4> f{};
  if (element == ElementKind::q1) {
    const double share = problem.load(x0 + 0.5 * h, y0 + 0.5 * h) * h * h / 4.0;
    f.fill(share);
    return f;
  }
  for (const auto& t : tri) {
    double cx = 0, cy = 0;
    for (int a : t) cx += node_x[a], cy += node_y[a];
    const double share = problem.load(x0 + h * cx / 3.0, y0 + h * cy / 3.0) * (h * h / 2.0) / 3.0;
    for (int a : t) f[a] += share;
  }
  return f;
}

}  // namespace htfeti
