// Problem files (DESIGN.md, "Problem files"): a TOML file that names a mesh (a Gmsh file or a
// generated box), the physics, conditions on named groups, the decomposition, the solver options
// and the outputs. read_problem_file() checks every key and type (an unknown key, a wrong type or
// a value out of range is a std::invalid_argument naming the key); make_model() reads the mesh,
// checks that every named group exists (a message listing the groups the mesh has) and returns
// the model. Relative mesh paths are relative to the problem file.
//
//   [mesh]        file = "part.msh" | generator = "box", size = [..], elements = [..],
//                 element = "quad4" | "tri3" | "hex8" | "tet4" | builtin = "membranes" (a
//                 built-in problem: elements = n, element = "q1" | "p1"; no [physics] then)
//   [physics]     type = "laplace" (source = number or expression) | "elasticity" (young,
//                 poisson, density, gravity = [..]); coefficient = expression (both)
//   [[dirichlet]] group, value (number or array), components (optional: [0, 2] or ["x", "z"])
//   [[load]]      group, traction = [..] (a boundary group) | source = number (a volume group,
//                 Laplace) | force = [..] (a volume group, elasticity: force per unit volume)
//   [[contact]]   group, direction = [..] (the obstacle's outward normal n), gap = expression:
//                 n.u <= gap(x, y, z) on every node of the group
//   [decomposition] subdomains = N (METIS) or [sx, sy(, sz)] (generated box), cluster_size,
//                 glue = "corners" | "averages" | "corners+averages"
//   [solver], [output]  every option of the options table (options.hpp; `htfeti solve --help`
//                 and docs/user-guide.md list them)
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/box.hpp"
#include "htfeti/model.hpp"
#include "htfeti/options.hpp"

namespace htfeti {

struct ProblemSpec {
  std::string path;  ///< the problem file
  /// [mesh] builtin = "poisson2d" | "membranes" | "membranes-coercive": a built-in problem, with
  /// elements = n and element = "q1" | "p1"; [decomposition] subdomains = N_s per side.
  std::string builtin;
  DecompositionOptions builtin_options;
  std::string mesh_file;  ///< resolved; empty for a generated box
  BoxGridOptions box;     ///< generator = "box" (subdomains/cluster_size filled from below)
  Physics physics;
  std::string source = "0";  ///< Laplace source: a number or an expression in x, y, z
  struct Dirichlet {
    std::string group;
    std::array<double, 3> value{0, 0, 0};
    std::vector<int> components;  ///< empty: all
  };
  struct Load {
    std::string group;
    enum Kind { traction, source, force } kind = traction;
    std::array<double, 3> value{0, 0, 0};
  };
  struct Contact {
    std::string group;
    std::array<double, 3> direction{0, 0, -1};
    std::string gap = "0";
  };
  std::vector<Dirichlet> dirichlet;
  std::vector<Load> loads;
  std::vector<Contact> contact;
  std::vector<int> subdomains{1};  ///< one number (METIS) or one per axis (generated box)
  int cluster_size = 1;
  Glue glue = Glue::averages;
};

/// Parses and checks a problem file; the [solver] and [output] tables are read through the
/// options table (options.hpp) into `run`, whose fields keep their values where the file is
/// silent.
ProblemSpec read_problem_file(const std::string& path, RunOptions& run);

/// Parses strictly a list of positive integers "8" or "2,4,2" (no signs, spaces, hex).
std::vector<int> parse_int_list(const std::string& text, const std::string& what);

/// The cube-obstacle benchmark (DESIGN.md; the paper's Table 4, ESPRESO's former obstacle
/// benchmark): the cube [0,100]^3 of hex8 elements (nx, ny, nz), clamped on x = 0, under its own
/// weight (density 7850, gravity -9.8066 in z), E = 2.1e7, nu = 0.3, in frictionless contact on
/// z = 0 with a rigid obstacle u_z >= -amplitude sin(pi x / 50) (direction (0,0,-1), gap
/// amplitude sin(pi x / 50)); subdomains (sx, sy, sz), clusters of m x m x m.
ProblemSpec cube_obstacle_spec(const std::vector<int>& elements, const std::vector<int>& subdomains,
                               int cluster_size, double amplitude = 1.0,
                               CellType cell = CellType::hex8);

/// Builds the model (reads and partitions the mesh). Throws std::invalid_argument for input
/// that does not fit (missing groups, sizes).
std::unique_ptr<Model> make_model(const ProblemSpec& spec);

}  // namespace htfeti
