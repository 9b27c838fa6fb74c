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

#include <string>
#include <vector>

#include "htfeti/model/problem_spec.hpp"
#include "htfeti/options.hpp"

namespace htfeti {

/// Parses and checks a problem file; the [solver] and [output] tables are read through the
/// options table (options.hpp) into `run`, whose fields keep their values where the file is
/// silent.
ProblemSpec read_problem_file(const std::string& path, RunOptions& run);

/// Parses strictly a list of positive integers "8" or "2,4,2" (no signs, spaces, hex).
std::vector<int> parse_int_list(const std::string& text, const std::string& what);

}  // namespace htfeti
