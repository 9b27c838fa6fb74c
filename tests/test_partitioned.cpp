// Meshes partitioned in advance by Gmsh, one file per part (mesh.parts): every rank reads only
// the parts of its own clusters. Checked against the undecomposed problem on the whole mesh
// (Eigen's sparse LU, independent of FETI and CHOLMOD), against the same solve on one rank (bit
// for bit), for what each rank holds, and for the refusals of bad part files. The parts are
// written at build time by the gmsh program (tests/CMakeLists.txt): the plate with a hole (tri3)
// in 6 parts, the bracket (tet4) in 8, the sphere on its block (contact between two bodies) in 6.
// Runs under mpiexec -n 1, 2, 3, 4.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "htfeti/mesh/mesh.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

const std::string kMeshes = HTFETI_SOURCE_DIR "/examples/meshes/";
const std::string kParts = HTFETI_BINARY_DIR "/";

ProblemSpec plate_strain(bool parts) {
  ProblemSpec s;
  (parts ? s.mesh_parts : s.mesh_file) =
      parts ? kParts + "plate-with-hole-parts.msh" : kMeshes + "plate-with-hole.msh";
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.material = {2.1e5, 0.3};
  s.dirichlet.push_back({"left", {0, 0, 0}, {}});
  s.loads.push_back({"right", ProblemSpec::Load::traction, {100.0, 20.0, 0}});
  s.subdomains.clear();
  return s;
}

ProblemSpec bracket_laplace(bool parts) {
  ProblemSpec s;
  (parts ? s.mesh_parts : s.mesh_file) =
      parts ? kParts + "bracket-parts.msh" : kMeshes + "bracket.msh";
  s.physics.kind = PhysicsKind::laplace;
  s.source = "1 + x*y";
  s.dirichlet.push_back({"x0", {0, 0, 0}, {}});
  s.dirichlet.push_back({"hole", {0.5, 0.5, 0.5}, {}});
  s.subdomains.clear();
  return s;
}

// The undecomposed problem on the whole mesh, solved by Eigen's sparse LU: u per global dof
// (the whole mesh numbers its nodes by Gmsh tag, as the parts do) and the energy.
std::pair<Eigen::VectorXd, double> solve_whole(ProblemSpec spec) {
  spec.subdomains = {1};
  spec.cluster_size = 1;
  const test::DirectSolution d = test::solve_one_subdomain(*make_model(spec));
  EXPECT_TRUE(d.factored);
  return {d.u, d.energy};
}

// The solve over every rank and the same solve on this rank alone (MPI_COMM_SELF: a partitioned
// mesh reads every part, a whole mesh is split here) give the same bits.
void expect_same_bits_as_one_rank(const ProblemSpec& spec, const SolveOptions& opt) {
  Comm comm, self(MPI_COMM_SELF);
  const auto all = solve(make_model(spec, &comm), opt, comm);
  const auto one = solve(make_model(spec, &self), opt, self);
  ASSERT_TRUE(one.converged) << one.report["stop_reason"];
  const double a = all.report["objective"], b = one.report["objective"];
  EXPECT_EQ(a, b);
  EXPECT_EQ(all.report["F_applications"], one.report["F_applications"]);
  EXPECT_EQ(all.report["displacement"], one.report["displacement"]);
  for (const char* key : {"contact_summary", "partitioner"}) {  // const: look up, never insert
    ASSERT_EQ(all.report.contains(key), one.report.contains(key)) << key;
    if (all.report.contains(key)) EXPECT_EQ(all.report.at(key), one.report.at(key)) << key;
  }
}

struct Case {
  const char* name;
  ProblemSpec (*spec)(bool parts);
  int cluster_size;
};

class PartitionedInput : public ::testing::TestWithParam<Case> {};

TEST_P(PartitionedInput, SameSolutionAsTheWholeMeshUndecomposed) {
  const Case c = GetParam();
  Comm comm;
  ProblemSpec spec = c.spec(true);
  spec.cluster_size = c.cluster_size;
  std::shared_ptr<const Model> model = make_model(spec, &comm);
  SolveOptions opt;
  opt.rtol = 1e-12;
  opt.max_iterations = 5000;
  const auto out = solve(model, opt, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const auto [ref, energy] = solve_whole(c.spec(false));
  EXPECT_EQ(model->num_nodes() * model->physics().dofs_per_node(), ref.size());
  EXPECT_LT(test::relative_error(*model, *out.dual, out.u, ref), 1e-8);
  EXPECT_NEAR(out.report["objective"].get<double>(), energy, 1e-9 * std::abs(energy));
  EXPECT_EQ(out.report["partitioner"], "gmsh parts");
  if (c.cluster_size > 1) EXPECT_LT(model->num_clusters(), model->num_subdomains());
}

// The same solve on this rank alone (MPI_COMM_SELF, reading every part) gives the same bits.
TEST_P(PartitionedInput, SameBitsOnEveryRankCount) {
  const Case c = GetParam();
  ProblemSpec spec = c.spec(true);
  spec.cluster_size = c.cluster_size;
  SolveOptions opt;
  opt.rtol = 1e-10;
  expect_same_bits_as_one_rank(spec, opt);
}

// Every rank holds the parts of its own clusters and nothing else; together they hold every
// cell once.
TEST_P(PartitionedInput, EachRankHoldsOnlyItsOwnParts) {
  const Case c = GetParam();
  Comm comm;
  ProblemSpec spec = c.spec(true);
  spec.cluster_size = c.cluster_size;
  const auto model = make_model(spec, &comm);
  const Mesh whole = read_gmsh(c.spec(false).mesh_file);
  const Model::MeshCounts held = model->held();
  long long cells = held.cells, points = held.points;
  MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &points, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(cells, whole.num_cells());
  EXPECT_EQ(points, model->primal_dimension() / model->physics().dofs_per_node());
  EXPECT_EQ(model->num_nodes(), whole.num_nodes());
  const FetiLayout L = model->layout();
  const auto [c0, c1] = L.cluster_range(comm.rank(), comm.size());
  long long mine = 0;
  for (int s = 0; s < model->num_subdomains(); ++s) {
    const bool own = s >= L.cluster_first[c0] && s < L.cluster_first[c1];
    if (own) {
      mine += model->mesh(s).num_cells();
      EXPECT_EQ(model->mesh_counts(s).cells, model->mesh(s).num_cells());
    } else {
      EXPECT_THROW(model->mesh(s), std::logic_error) << "subdomain " << s;
    }
  }
  EXPECT_EQ(mine, held.cells);
  if (comm.size() > 1) EXPECT_LT(held.cells, whole.num_cells());
}

INSTANTIATE_TEST_SUITE_P(Meshes, PartitionedInput,
                         ::testing::Values(Case{"plane_strain_tri3_tfeti", plate_strain, 1},
                                           Case{"plane_strain_tri3_clusters", plate_strain, 3},
                                           Case{"laplace_tet4_tfeti", bracket_laplace, 1},
                                           Case{"laplace_tet4_clusters", bracket_laplace, 4}),
                         [](const auto& info) { return std::string(info.param.name); });

// A copy of the bracket's parts in a directory of this test's own, to be damaged.
std::string copy_parts(const std::string& dir) {
  Comm comm;  // one directory per rank count: ctest runs them side by side
  const std::string out = kParts + dir + "-np" + std::to_string(comm.size()) + "/";
  if (comm.rank() == 0) {
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    for (int k = 1; k <= 8; ++k)
      std::filesystem::copy_file(kParts + "bracket-parts_" + std::to_string(k) + ".msh",
                                 out + "b_" + std::to_string(k) + ".msh");
  }
  MPI_Barrier(MPI_COMM_WORLD);
  return out;
}

// Refused with std::invalid_argument on every rank, with a message containing `what`.
void expect_refused(ProblemSpec spec, const std::string& what) {
  Comm comm;
  try {
    make_model(spec, &comm);
    ADD_FAILURE() << "accepted; expected: " << what;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

// The bracket's problem on the parts NAME_k.msh in `dir` (once rank 0 has changed them): refused.
void expect_parts_refused(const std::string& dir, const std::string& name,
                          const std::string& what) {
  MPI_Barrier(MPI_COMM_WORLD);
  ProblemSpec s = bracket_laplace(true);
  s.mesh_parts = dir + name;
  expect_refused(s, what);
}

// Contact between bodies on a mesh partitioned in advance: examples/sphere-on-block.toml (a
// sphere pressed on a block, mortar rows) on Gmsh's 6 parts. The contact surfaces are gathered
// from the parts; rows, bodies and solution must be those of the same mesh read whole and split
// by METIS into 6 (another decomposition of the same discrete problem).
ProblemSpec sphere_on_block(bool parts, SolveOptions& opt) {
  RunOptions run;
  ProblemSpec s = read_problem_file(HTFETI_SOURCE_DIR "/examples/sphere-on-block.toml", run);
  opt = run.solve;
  opt.rtol = 1e-10;
  opt.max_iterations = 20000;
  if (parts) {
    s.mesh_file.clear();
    s.mesh_parts = kParts + "sphere-on-block-parts.msh";
    s.subdomains.clear();
  } else {
    s.subdomains = {6};
  }
  return s;
}

TEST(PartitionedContact, SameRowsBodiesAndSolutionAsTheWholeMesh) {
  Comm comm;
  // Gmsh puts cells of both bodies into one of the parts: a part's pieces are joined to bodies.
  int crossing = 0;
  for (int k = 1; k <= 6; ++k) {
    const Mesh p = read_gmsh(kParts + "sphere-on-block-parts_" + std::to_string(k) + ".msh");
    const std::vector<int> comp = node_components(p.cells, cell_nodes(p.type), p.num_nodes());
    int pieces = 0;
    for (int v = 0; v < p.num_nodes(); ++v) pieces += comp[v] == v;
    crossing += pieces > 1;
  }
  EXPECT_GE(crossing, 1) << "no part of both bodies: the case below would not cover it";
  SolveOptions opt;
  const auto parts = solve(make_model(sphere_on_block(true, opt), &comm), opt, comm);
  ASSERT_TRUE(parts.converged) << parts.report["stop_reason"];
  const auto whole = solve(make_model(sphere_on_block(false, opt), &comm), opt, comm);
  ASSERT_TRUE(whole.converged) << whole.report["stop_reason"];
  EXPECT_EQ(parts.report["partitioner"], "gmsh parts");
  EXPECT_EQ(parts.report["bodies"], 2);
  const auto &cp = parts.report["conditions"]["contact"][0],
             &cw = whole.report["conditions"]["contact"][0];
  for (const char* key : {"rows", "slave_bodies", "master_bodies", "search_distance"})
    EXPECT_EQ(cp[key], cw[key]) << key;
  const double e = parts.report["objective"], ew = whole.report["objective"];
  EXPECT_NEAR(e, ew, 1e-8 * std::abs(ew));
  const auto &sp = parts.report["contact_summary"][0], &sw = whole.report["contact_summary"][0];
  EXPECT_EQ(sp["active_rows"], sw["active_rows"]);
  const double load = -parts.report["load_resultant"][2].get<double>();
  EXPECT_NEAR(sp["resultant"][2].get<double>(), load, 1e-3 * load);
  EXPECT_LT(sp["max_penetration"].get<double>(), 1e-6);
}

TEST(PartitionedContact, SameBitsOnEveryRankCount) {
  SolveOptions opt;
  const ProblemSpec spec = sphere_on_block(true, opt);
  opt.rtol = 1e-8;
  expect_same_bits_as_one_rank(spec, opt);
}

// Slave and master on one body, known only once the parts' pieces are joined into bodies: refused
// on every rank, as for a whole mesh.
TEST(PartitionedContact, SlaveAndMasterOnOneBodyAreRefused) {
  SolveOptions opt;
  ProblemSpec s = sphere_on_block(true, opt);
  s.contact[0].master = "sphere_top";
  expect_refused(s, "lie on the same body");
}

// A whole mesh (mesh.file, or a generated box split by METIS) on several ranks: rank 0 reads or
// generates it, splits it, and sends every rank the subdomains of its clusters. The other ranks
// never hold the whole mesh; the results are those of one rank, bit for bit.
ProblemSpec box_by_metis(bool) {
  ProblemSpec s = cube_obstacle_spec({8, 8, 8}, {1, 1, 1}, 1);
  s.subdomains = {12};
  return s;
}
ProblemSpec box_by_metis_clusters(bool) {
  ProblemSpec s = box_by_metis(false);
  s.cluster_size = 3;
  return s;
}
ProblemSpec plate_by_metis(bool) {
  ProblemSpec s = plate_strain(false);
  s.subdomains = {6};
  return s;
}
ProblemSpec bracket_by_metis(bool) {
  ProblemSpec s = bracket_laplace(false);
  s.subdomains = {8};
  return s;
}
ProblemSpec sphere_whole(bool) {
  SolveOptions opt;
  return sphere_on_block(false, opt);
}

class WholeMeshSplitOnRankZero : public ::testing::TestWithParam<Case> {};

TEST_P(WholeMeshSplitOnRankZero, SameBitsAsOneRank) {
  SolveOptions opt;
  opt.rtol = 1e-8;
  opt.max_iterations = 5000;
  expect_same_bits_as_one_rank(GetParam().spec(false), opt);
}

TEST_P(WholeMeshSplitOnRankZero, EachRankHoldsOnlyItsOwnSubdomains) {
  Comm comm;
  const ProblemSpec spec = GetParam().spec(false);
  const auto model = make_model(spec, &comm);
  const auto whole = make_model(spec);  // this rank alone: every subdomain
  const Model::MeshCounts held = model->held();
  long long cells = held.cells;
  MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPI_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  long long total = 0;
  for (int s = 0; s < whole->num_subdomains(); ++s) total += whole->mesh(s).num_cells();
  EXPECT_EQ(cells, total);
  const FetiLayout L = model->layout();
  const auto [c0, c1] = L.cluster_range(comm.rank(), comm.size());
  for (int s = 0; s < model->num_subdomains(); ++s) {
    EXPECT_EQ(model->mesh_counts(s).cells, whole->mesh(s).num_cells()) << s;
    if (comm.size() == 1 || (s >= L.cluster_first[c0] && s < L.cluster_first[c1])) {
      const SubdomainMesh a = model->mesh(s), b = whole->mesh(s);
      EXPECT_EQ(a.global_node, b.global_node);
      EXPECT_EQ(a.coords, b.coords);
      EXPECT_EQ(a.cells, b.cells);
      EXPECT_EQ(a.copy_list, b.copy_list);
      EXPECT_EQ(a.node_groups, b.node_groups);
    } else {
      EXPECT_THROW(model->mesh(s), std::logic_error) << "subdomain " << s;
    }
  }
  if (comm.size() > 1) EXPECT_LT(held.cells, total);
}

INSTANTIATE_TEST_SUITE_P(Meshes, WholeMeshSplitOnRankZero,
                         ::testing::Values(Case{"plane_strain_tri3", plate_by_metis, 1},
                                           Case{"laplace_tet4", bracket_by_metis, 1},
                                           Case{"box_hex8", box_by_metis, 1},
                                           Case{"box_hex8_clusters", box_by_metis_clusters, 3},
                                           Case{"sphere_on_block_pairs", sphere_whole, 1}),
                         [](const auto& info) { return std::string(info.param.name); });

// Bad input found on rank 0 alone (a missing mesh file) is refused on every rank.
TEST(WholeMeshSplitOnRankZeroErrors, AMissingMeshFileIsRefusedEverywhere) {
  ProblemSpec s = bracket_by_metis(false);
  s.mesh_file = kMeshes + "no-such-mesh.msh";
  expect_refused(s, "no-such-mesh.msh");
}

TEST(PartitionedInputErrors, MissingPartFile) {
  const std::string dir = copy_parts("parts-missing");
  Comm comm;
  if (comm.rank() == 0) std::filesystem::remove(dir + "b_7.msh");
  expect_parts_refused(dir, "b.msh", "part 7 of");
}

TEST(PartitionedInputErrors, SubdomainsThatDoNotMatchTheParts) {
  ProblemSpec s = bracket_laplace(true);
  s.subdomains = {6};
  expect_refused(s, "does not match the 8 parts");
}

TEST(PartitionedInputErrors, PartsOfTwoPartitions) {
  const std::string dir = copy_parts("parts-mixed");
  Comm comm;
  if (comm.rank() == 0)  // part 3 of the plate's 6-part partition in place of the bracket's
    std::filesystem::copy_file(kParts + "plate-with-hole-parts_3.msh", dir + "b_3.msh",
                               std::filesystem::copy_options::overwrite_existing);
  expect_parts_refused(dir, "b.msh", "parts");
}

// An interface node moved in one part file: the parts no longer describe one mesh.
TEST(PartitionedInputErrors, InterfaceNodesThatDisagree) {
  const std::string dir = copy_parts("parts-moved");
  Comm comm;
  if (comm.rank() == 0) {
    // Part 2's nodes that part 1 holds too: move the first of them in part 2's file.
    const Mesh p1 = read_gmsh(dir + "b_1.msh"), p2 = read_gmsh(dir + "b_2.msh");
    std::size_t shared = 0;
    for (std::size_t t : p2.node_tags)
      if (std::binary_search(p1.node_tags.begin(), p1.node_tags.end(), t)) {
        shared = t;
        break;
      }
    ASSERT_NE(shared, 0u) << "parts 1 and 2 share no node";
    std::ifstream in(dir + "b_2.msh");
    std::stringstream text;
    text << in.rdbuf();
    in.close();
    // MSH 4.1 ASCII: the node block lists the tags, then one "x y z" line per tag.
    std::string s = text.str();
    const size_t nodes = s.find("$Nodes");
    std::istringstream lines(s.substr(nodes));
    std::string line;
    std::vector<std::string> all;
    while (std::getline(lines, line)) all.push_back(line);
    bool moved = false;
    const int blocks = std::stoi(all[1]);
    size_t i = 2;
    for (int b = 0; b < blocks && !moved; ++b) {
      std::istringstream h(all[i]);
      long long dim, entity, param, n;
      h >> dim >> entity >> param >> n;
      for (long long j = 0; j < n; ++j)
        if (std::stoull(all[i + 1 + j]) == shared) {  // x moved by 1e-9 of the bracket's size
          std::istringstream xyz(all[i + 1 + n + j]);
          double x, y, z;
          xyz >> x >> y >> z;
          std::ostringstream o;
          o.precision(17);
          o << x + 1e-9 << " " << y << " " << z;
          all[i + 1 + n + j] = o.str();
          moved = true;
        }
      i += 1 + 2 * n;
    }
    ASSERT_TRUE(moved);
    std::ofstream out(dir + "b_2.msh");
    out << s.substr(0, nodes);
    for (const auto& l : all) out << l << "\n";
  }
  expect_parts_refused(dir, "b.msh", "the part files are not of one mesh");
}

TEST(PartitionedInputErrors, AWholeMeshIsNotAPart) {
  const std::string dir = copy_parts("parts-whole");
  Comm comm;
  if (comm.rank() == 0)
    std::filesystem::copy_file(kMeshes + "bracket.msh", dir + "w_1.msh",
                               std::filesystem::copy_options::overwrite_existing);
  expect_parts_refused(dir, "w.msh", "is not one part of a partitioned mesh");
}

}  // namespace
