// The built-in benchmark problems of DESIGN.md and their discretization on a regular grid.
//
// Geometry: one unit square (poisson2d) or two, Omega1 = (0,1)^2 and Omega2 = (1,2)x(0,1)
// (membranes), each with n elements per side (h = 1/n) and nodes of its own: the two membranes
// have separate nodes on x = 1. Elements are Q1 (bilinear) or P1 (each grid square split by the
// diagonal from its lower-left to its upper-right corner). The load of an element is f at its
// centroid times the element's share: area/4 per node for Q1, area/3 per node for P1.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"

namespace htfeti {

enum class ProblemKind { poisson2d, membranes, membranes_coercive };
enum class ElementKind { q1, p1 };

inline constexpr std::array<EnumName<ProblemKind>, 3> kProblemNames{
    {{ProblemKind::poisson2d, "poisson2d"},
     {ProblemKind::membranes, "membranes"},
     {ProblemKind::membranes_coercive, "membranes-coercive"}}};
ProblemKind parse_problem(const std::string& name);  // throws std::invalid_argument
std::string to_string(ProblemKind kind);
inline constexpr std::array<EnumName<ElementKind>, 2> kElementNames{
    {{ElementKind::q1, "q1"}, {ElementKind::p1, "p1"}}};
ElementKind parse_element(const std::string& name);  // throws std::invalid_argument
std::string to_string(ElementKind kind);

/// The continuous problem: squares, load and which sides are Dirichlet.
struct Problem {
  ProblemKind kind = ProblemKind::poisson2d;
  int squares() const { return kind == ProblemKind::poisson2d ? 1 : 2; }
  bool has_contact() const { return kind != ProblemKind::poisson2d; }
  /// Load f at point (x, y); x in (q, q+1) for square q.
  double load(double x, double y) const;
  /// Whether node (gx, gy) of square q (grid n) carries u = 0.
  bool dirichlet(int q, int gx, int gy, int n) const;
};

/// Element stiffness of one grid square (4x4, nodes ordered (0,0),(1,0),(1,1),(0,1)) for
/// -Laplace u. In 2D it does not depend on h.
std::array<std::array<double, 4>, 4> square_stiffness(ElementKind element);

/// Nodal load of one grid square with lower-left corner (x0, y0) and side h, same node order.
std::array<double, 4> square_load(const Problem& problem, ElementKind element, double x0, double y0,
                                  double h);

}  // namespace htfeti
