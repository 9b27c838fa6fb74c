// The general pipeline against the undecomposed problem: Laplace on unstructured Gmsh meshes with
// a hole (tri3, tet4) split by METIS, plane-strain elasticity on the 2D mesh, hex8 elasticity on a
// generated box, each with TFETI and H-TFETI-DP (averages, corners). The reference is the same
// problem as one subdomain (no decomposition), Dirichlet dofs eliminated, solved by Eigen's sparse
// LU. Runs under mpiexec -n 1, 2, 3.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <map>
#include <set>

#include "helpers.hpp"
#include "htfeti/mesh/mesh.hpp"
#include "htfeti/partition/partition.hpp"
#include "htfeti/problem_file.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

const std::string kMeshes = HTFETI_SOURCE_DIR "/examples/meshes/";

struct Reference {
  Eigen::VectorXd u;  ///< per global dof (node * dofs_per_node + component)
  double energy = 0;
};

// The undecomposed problem: the model's spec with one subdomain.
Reference solve_directly(ProblemSpec spec) {
  spec.subdomains =
      std::vector<int>(spec.subdomains.size() > 1 && spec.mesh_file.empty() ? spec.box.dim : 1, 1);
  spec.cluster_size = 1;
  const test::DirectSolution d = test::solve_one_subdomain(*make_model(spec));
  EXPECT_TRUE(d.factored);
  return {d.u, d.energy};
}

ProblemSpec laplace_on(const std::string& mesh, const std::string& zero_group,
                       const std::string& one_group) {
  ProblemSpec s;
  s.mesh_file = kMeshes + mesh;
  s.physics.kind = PhysicsKind::laplace;
  s.source = "1 + x*y";
  s.dirichlet.push_back({zero_group, {0, 0, 0}, {}});
  s.dirichlet.push_back({one_group, {0.5, 0.5, 0.5}, {}});
  return s;
}

ProblemSpec plane_strain_plate() {
  ProblemSpec s;
  s.mesh_file = kMeshes + "plate-with-hole.msh";
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.material = {2.1e5, 0.3};
  s.physics.density = 1.0;
  s.physics.gravity = {0, -9.81, 0};
  s.dirichlet.push_back({"left", {0, 0, 0}, {}});
  s.loads.push_back({"right", ProblemSpec::Load::traction, {100.0, 20.0, 0}});
  return s;
}

ProblemSpec hex8_box() {
  ProblemSpec s;
  s.box.dim = 3;
  s.box.cell = CellType::hex8;
  s.box.size = {4, 1, 1};
  s.box.elements = {16, 8, 8};
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.material = {2.1e7, 0.3};
  s.physics.density = 7850;
  s.physics.gravity = {0, 0, -9.8066};
  s.dirichlet.push_back({"x0", {0, 0, 0}, {}});
  s.dirichlet.push_back({"x1", {0.001, 0, 0}, {0}});  // a prescribed displacement in x only
  s.loads.push_back({"z1", ProblemSpec::Load::traction, {0, 1e3, -1e4}});
  return s;
}

// A 5 x 5 quad4 square on its bottom, pressed on top: METIS splits it into 3, 4 and 6 parts
// with a subdomain whose cells touch only at a node (a mechanism; with 4 parts htfeti used to
// return a wrong energy with exit 0), which partition_mesh now splits again into connected
// parts.
ProblemSpec hinged_square() {
  ProblemSpec s;
  s.box.dim = 2;
  s.box.cell = CellType::quad4;
  s.box.size = {1, 1, 0};
  s.box.elements = {5, 5, 0};
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.material = {1000, 0.3};
  s.dirichlet.push_back({"y0", {0, 0, 0}, {}});
  s.loads.push_back({"y1", ProblemSpec::Load::traction, {1, -10, 0}});
  return s;
}

struct Case {
  const char* name;
  ProblemSpec (*spec)();
  std::vector<int> subdomains;
  int cluster_size;
  Glue glue;
  PartitionObjective objective = PartitionObjective::volume;
  PartitionShape shape = PartitionShape::compact;
};

// The box of hex8_box meshed with stretched cells (0.5 x 0.125 x 0.125: faces 4 : 1), which the
// automatic objective splits by facet area.
ProblemSpec hex8_stretched_box() {
  ProblemSpec s = hex8_box();
  s.box.elements = {8, 8, 8};
  return s;
}

ProblemSpec laplace_plate() { return laplace_on("plate-with-hole.msh", "left", "hole"); }
ProblemSpec laplace_bracket() { return laplace_on("bracket.msh", "x0", "hole"); }

// Coefficient jumps of 1e3 that a METIS split must not straddle (partition.hpp): the plate's
// right part conducts better, the box's far end is stiffer.
ProblemSpec laplace_plate_jump() {
  ProblemSpec s = laplace_plate();
  s.physics.coefficient = "x > 1 ? 1000 : 1";
  return s;
}
ProblemSpec hex8_box_jump() {
  ProblemSpec s = hex8_box();
  s.physics.coefficient = "x > 2.6 ? 1000 : 1";
  return s;
}

// Every element type and physics, with a coefficient field too, split in a few subdomains: the
// cases of the element-wise checks below.
std::vector<ProblemSpec> element_cases() {
  std::vector<ProblemSpec> specs{laplace_plate(), laplace_bracket(), plane_strain_plate(),
                                 hex8_box()};
  specs.push_back(plane_strain_plate());
  specs.back().physics.coefficient = "1 + 100 * (x > 0.5)";
  for (auto& spec : specs) {
    spec.subdomains = std::vector<int>(spec.mesh_file.empty() ? spec.box.dim : 1, 2);
    if (!spec.mesh_file.empty()) spec.subdomains = {4};
  }
  return specs;
}

// The energy of the report is computed element by element once K_i is freed: the same u'K u as
// the assembled matrix, for every element type and physics, with a coefficient field too.
TEST(Energy, ElementwiseFormEqualsTheAssembledMatrix) {
  for (const auto& spec : element_cases()) {
    const auto model = make_model(spec);
    for (int s = 0; s < std::min(3, model->num_subdomains()); ++s) {
      const SubdomainMesh mesh = model->mesh(s);
      const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, model->physics());
      const Eigen::VectorXd u = Eigen::VectorXd::Random(K.rows());
      const double assembled = u.dot(K * u);
      EXPECT_GT(assembled, 0);
      EXPECT_NEAR(stiffness_form(mesh, model->physics(), u), assembled, 1e-12 * assembled)
          << spec.mesh_file << " subdomain " << s;
    }
  }
}

// assemble_stiffness sums the element contributions by column in its own work arrays; the
// matrix is Eigen's setFromTriplets of the same contributions bit for bit (pattern and values),
// for every element type and physics, with a coefficient field, and twice in a row on one
// thread (the kept work arrays), and on a generated box's period-cached element matrices.
TEST(Assembly, StiffnessIsTheTripletsSummedInElementOrder) {
  int checked = 0;
  for (const auto& spec : element_cases()) {
    const auto model = make_model(spec);
    for (int s = 0; s < std::min(3, model->num_subdomains()); ++s) {
      const SubdomainMesh mesh = model->mesh(s);
      const auto trip = stiffness_triplets(mesh, model->physics());
      const long n = static_cast<long>(mesh.num_nodes()) * model->physics().dofs_per_node();
      Eigen::SparseMatrix<double> ref(n, n);
      ref.setFromTriplets(trip.begin(), trip.end());
      for (int pass = 0; pass < 2; ++pass) {
        const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, model->physics());
        ASSERT_EQ(K.rows(), n);
        ASSERT_TRUE(K.isCompressed());
        ASSERT_EQ(K.nonZeros(), ref.nonZeros()) << spec.mesh_file << " subdomain " << s;
        EXPECT_TRUE(
            std::equal(ref.outerIndexPtr(), ref.outerIndexPtr() + n + 1, K.outerIndexPtr()));
        EXPECT_TRUE(std::equal(ref.innerIndexPtr(), ref.innerIndexPtr() + ref.nonZeros(),
                               K.innerIndexPtr()));
        long differ = 0;  // bit for bit: the same sums in the same order
        for (long k = 0; k < ref.nonZeros(); ++k)
          differ += std::memcmp(ref.valuePtr() + k, K.valuePtr() + k, sizeof(double)) != 0;
        EXPECT_EQ(differ, 0) << spec.mesh_file << " subdomain " << s;
        ++checked;
      }
    }
  }
  EXPECT_GE(checked, 20);
}

// The VTU writer places each subdomain's values by Model::mesh_counts: on generated boxes
// (arithmetic) and on split meshes (the default, from the mesh) they are the sizes of mesh(s),
// for every cell type.
TEST(Model, MeshCountsAreTheSizesOfTheMesh) {
  std::vector<ProblemSpec> specs{laplace_plate(), plane_strain_plate()};
  for (CellType cell : {CellType::quad4, CellType::tri3, CellType::hex8, CellType::tet4}) {
    specs.push_back(hex8_box());
    specs.back().box.cell = cell;
    if (cell == CellType::quad4 || cell == CellType::tri3) {  // a 2D box: no z faces
      specs.back().box.dim = 2;
      specs.back().loads.clear();
    }
  }
  for (auto& spec : specs) {
    spec.subdomains =
        spec.mesh_file.empty() ? std::vector<int>(spec.box.dim, 2) : std::vector<int>{3};
    const auto model = make_model(spec);
    for (int s = 0; s < model->num_subdomains(); ++s) {
      const SubdomainMesh mesh = model->mesh(s);
      const Model::MeshCounts c = model->mesh_counts(s);
      EXPECT_EQ(c.points, mesh.num_nodes()) << spec.mesh_file << " " << s;
      EXPECT_EQ(c.cells, mesh.num_cells()) << spec.mesh_file << " " << s;
      EXPECT_EQ(c.corners, static_cast<long long>(mesh.cells.size())) << spec.mesh_file << " " << s;
    }
  }
}

// Each node's copy list names exactly the subdomains whose meshes hold that global node (found
// here by collecting every subdomain's nodes), on boxes in 2D and 3D with clusters and on a split
// Gmsh mesh.
TEST(Model, NodeCopiesAreTheSubdomainsHoldingTheNode) {
  std::vector<ProblemSpec> specs{laplace_plate()};
  specs.back().subdomains = {5};
  for (int dim : {2, 3}) {
    specs.push_back(hex8_box());
    auto& b = specs.back();
    if (dim == 2) b.box.dim = 2, b.box.cell = CellType::quad4, b.loads.clear();
    b.subdomains = std::vector<int>(dim, 4);
    b.cluster_size = 2;
  }
  for (const auto& spec : specs) {
    const auto model = make_model(spec);
    std::map<long long, std::set<int>> holders;
    std::vector<SubdomainMesh> meshes;
    for (int s = 0; s < model->num_subdomains(); ++s) {
      meshes.push_back(model->mesh(s));
      for (long long g : meshes.back().global_node) holders[g].insert(s);
    }
    long long shared = 0;
    for (const auto& m : meshes)
      for (int k = 0; k < m.num_nodes(); ++k) {
        const std::set<int> listed(m.copy_list.begin() + m.copy_offset[k],
                                   m.copy_list.begin() + m.copy_offset[k + 1]);
        ASSERT_EQ(listed, holders.at(m.global_node[k]))
            << spec.mesh_file << " subdomain " << m.id << " node " << k;
        ASSERT_EQ(listed.size(), static_cast<size_t>(m.num_copies(k)));
        shared += listed.size() > 1;
      }
    EXPECT_GT(shared, 0) << spec.mesh_file;
  }
}

class AgainstUndecomposed : public ::testing::TestWithParam<Case> {};

TEST_P(AgainstUndecomposed, SameSolution) {
  const Case c = GetParam();
  Comm comm;
  ProblemSpec spec = c.spec();
  spec.subdomains = c.subdomains;
  spec.cluster_size = c.cluster_size;
  spec.glue = c.glue;
  spec.partition_objective = c.objective;
  spec.partition_shape = c.shape;
  std::shared_ptr<const Model> model = make_model(spec);
  SolveOptions opt;
  opt.rtol = 1e-12;
  opt.max_iterations = 5000;
  const auto out = solve(model, opt, comm);
  ASSERT_TRUE(out.converged) << out.report["stop_reason"];
  const Reference ref = solve_directly(spec);
  EXPECT_LT(test::relative_error(*model, *out.dual, out.u, ref.u), 1e-8);
  const double energy = out.report["objective"];
  EXPECT_NEAR(energy, ref.energy, 1e-8 * std::abs(ref.energy));
  // The coarse space: the clusters' kernels; at least one kernel of the physics per cluster,
  // exactly that for TFETI on connected subdomains and for boxes of subdomains.
  const int k = model->physics().kernel_dimension();
  const int coarse = out.report["coarse_dimension"];
  EXPECT_GE(coarse, k * model->num_clusters());
  if (!spec.mesh_file.empty() && c.cluster_size == 1) {
    EXPECT_EQ(coarse, k * model->num_subdomains() * 1) << "disconnected METIS parts?";
  }
  if (spec.mesh_file.empty()) {
    EXPECT_EQ(coarse, k * model->num_clusters());
  }
  EXPECT_EQ(coarse, out.report["cluster_kernel_dimension_sum"].get<int>());
  if (!spec.physics.coefficient.empty()) {  // the jump cases: split at the jump, then weighted
    EXPECT_GT(out.report["partition_jump_regions"].get<int>(), 0);
    EXPECT_EQ(out.report["partition_jump_splits_declined"].get<int>(), 0);
    EXPECT_EQ(out.report["solver"]["pcg_projector"], "weighted");
  }
}

INSTANTIATE_TEST_SUITE_P(
    Meshes, AgainstUndecomposed,
    ::testing::Values(
        Case{"laplace_tri3_tfeti", laplace_plate, {8}, 1, Glue::averages},
        Case{"laplace_tri3_averages", laplace_plate, {12}, 4, Glue::averages},
        Case{"laplace_tri3_corners", laplace_plate, {12}, 4, Glue::corners},
        Case{"laplace_tet4_tfeti", laplace_bracket, {6}, 1, Glue::averages},
        Case{"laplace_tet4_averages", laplace_bracket, {8}, 4, Glue::averages},
        Case{"laplace_tet4_corners", laplace_bracket, {8}, 4, Glue::corners},
        Case{"plane_strain_tfeti", plane_strain_plate, {8}, 1, Glue::averages},
        Case{"plane_strain_averages", plane_strain_plate, {12}, 3, Glue::averages},
        Case{"hex8_box_tfeti", hex8_box, {4, 2, 2}, 1, Glue::averages},
        Case{"hex8_box_averages", hex8_box, {4, 2, 2}, 2, Glue::averages},
        Case{"hex8_box_metis", hex8_box, {6}, 3, Glue::averages},
        Case{"hex8_box_metis_shape",
             hex8_box,
             {6},
             1,
             Glue::averages,
             PartitionObjective::volume,
             PartitionShape::metis},
        Case{"plane_strain_metis_cut",
             plane_strain_plate,
             {8},
             1,
             Glue::averages,
             PartitionObjective::cut},
        Case{"hex8_box_metis_cut", hex8_box, {6}, 3, Glue::averages, PartitionObjective::cut},
        Case{"hex8_stretched_metis_auto",
             hex8_stretched_box,
             {6},
             1,
             Glue::averages,
             PartitionObjective::automatic},
        Case{"hex8_stretched_metis_area",
             hex8_stretched_box,
             {6},
             3,
             Glue::averages,
             PartitionObjective::area},
        Case{"plane_strain_metis_area",
             plane_strain_plate,
             {8},
             1,
             Glue::averages,
             PartitionObjective::area},
        Case{"laplace_tri3_jump_tfeti", laplace_plate_jump, {8}, 1, Glue::averages},
        Case{"hex8_box_jump_tfeti", hex8_box_jump, {6}, 1, Glue::averages},
        Case{"hex8_box_jump_averages", hex8_box_jump, {6}, 3, Glue::averages},
        Case{"hinged_square_3", hinged_square, {3}, 1, Glue::averages},
        Case{"hinged_square_4", hinged_square, {4}, 1, Glue::averages},
        Case{"hinged_square_6", hinged_square, {6}, 1, Glue::averages}),
    [](const auto& info) { return std::string(info.param.name); });

// nx x ny quad4 cells on [0, lx] x [0, ly], numbered row by row.
Mesh quad_strip(int nx, int ny, double lx, double ly) {
  Mesh m;
  m.dim = 2;
  m.type = CellType::quad4;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) m.coords.insert(m.coords.end(), {lx * i / nx, ly * j / ny, 0.0});
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i;
      m.cells.insert(m.cells.end(), {a, a + 1, a + nx + 2, a + nx + 1});
    }
  return m;
}

// Cells of 1 x 1/8 in a strip 8 x 1: every cell is stretched, so the automatic objective takes
// the facet area, and two parts are cut along x = 4 (8 short edges: length 1) and not along
// y = 1/2 (8 long edges: length 8), where the plain edge cut sees a tie.
TEST(Partition, AreaObjectiveCutsAcrossTheShortFacetsOfStretchedCells) {
  const Mesh mesh = quad_strip(8, 8, 8.0, 1.0);
  EXPECT_DOUBLE_EQ(stretched_cell_share(mesh), 1.0);
  const MeshPartition p = partition_mesh(mesh, 2, 1, PartitionObjective::automatic);
  EXPECT_EQ(p.objective, PartitionObjective::area);
  EXPECT_DOUBLE_EQ(p.stretched_share, 1.0);
  for (int j = 0; j < 8; ++j)
    for (int i = 0; i < 8; ++i)
      EXPECT_EQ(p.cell_subdomain[j * 8 + i], p.cell_subdomain[i < 4 ? 0 : 7]) << i << " " << j;
  EXPECT_NE(p.cell_subdomain[0], p.cell_subdomain[7]);
}

// The repair of a split in pieces or hinged (repair_parts) on a 6 x 6 square of quads, cell
// (i, j) = j * 6 + i: parts 0 (i < 3) and 1 (i >= 3), then
//  - a lone cell of part 0 inside part 1 (a piece): it moves to part 1, nothing else moves;
//  - part 0 in two blocks touching only at a node (hinged): the smaller block, which shares its
//    facets with part 1 only, moves there;
//  - more cells to move than max_share allows: -1, the split unchanged;
//  - a split without pieces: nothing moves.
TEST(Partition, RepairMovesPiecesToTheirNeighbour) {
  const Mesh square = quad_strip(6, 6, 6.0, 6.0);
  const auto halves = [] {
    std::vector<int> part(36);
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) part[j * 6 + i] = i < 3 ? 0 : 1;
    return part;
  };
  std::vector<int> part = halves();
  part[2 * 6 + 4] = 0;  // (4, 2): inside part 1
  EXPECT_EQ(repair_parts(square, part, 1.0), 1);
  EXPECT_EQ(part, halves());
  part = halves();  // part 0: rows 0-2 of i < 3, and the cell (3, 3) joined at a node
  for (int j = 3; j < 6; ++j)
    for (int i = 0; i < 3; ++i) part[j * 6 + i] = 1;
  part[3 * 6 + 3] = 0;
  std::vector<int> want = part;
  want[3 * 6 + 3] = 1;
  EXPECT_EQ(repair_parts(square, part, 1.0), 1);
  EXPECT_EQ(part, want);
  part = halves();
  part[2 * 6 + 4] = 0;
  const std::vector<int> before = part;
  EXPECT_EQ(repair_parts(square, part, 0.5 / 36), -1);
  EXPECT_EQ(part, before);
  part = halves();
  EXPECT_EQ(repair_parts(square, part, 1.0), 0);
  EXPECT_EQ(part, halves());
}

// Square cells: none stretched, the automatic objective is the communication volume; cells of
// 2.4 : 1 are not stretched either, 2.5 : 1 are (kStretchRatio).
TEST(Partition, AutomaticObjectiveKeepsTheVolumeOnRegularCells) {
  const Mesh square = quad_strip(8, 8, 8.0, 8.0);
  EXPECT_EQ(stretched_cell_share(square), 0.0);
  EXPECT_EQ(partition_mesh(square, 4, 1).objective, PartitionObjective::volume);
  EXPECT_EQ(stretched_cell_share(quad_strip(4, 4, 4 * 2.4, 4.0)), 0.0);
  EXPECT_EQ(stretched_cell_share(quad_strip(4, 4, 4 * 2.5, 4.0)), 1.0);
  EXPECT_EQ(partition_mesh(square, 4, 1, PartitionObjective::area).objective,
            PartitionObjective::area);
}

// METIS's seed: the same seed gives the same split, another seed another split, each a
// partition of all cells into the parts asked for, within METIS's balance and with every part
// in one piece (the repair holds for any seed).
TEST(Partition, SeedChoosesAmongSplitsAndRepeats) {
  const Mesh square = quad_strip(48, 48, 1.0, 1.0);
  const auto split = [&](int seed) {
    return partition_mesh(square, 12, 1, PartitionObjective::volume, ClusterSplit::mesh, seed);
  };
  const MeshPartition a = split(1), again = split(1), b = split(7);
  EXPECT_EQ(a.cell_subdomain, again.cell_subdomain);
  EXPECT_EQ(a.cell_subdomain,
            partition_mesh(square, 12, 1, PartitionObjective::volume).cell_subdomain)
      << "kDefaultPartitionSeed is the default";
  EXPECT_NE(a.cell_subdomain, b.cell_subdomain);
  for (const MeshPartition* p : {&a, &b}) {
    ASSERT_EQ(p->num_subdomains, 12);
    size_t cells = 0;
    for (const auto& c : p->subdomain_cells) {
      EXPECT_GE(c.size(), 48u * 48u / 12u * 9u / 10u);
      EXPECT_LE(c.size(), 48u * 48u / 12u * 11u / 10u);
      cells += c.size();
    }
    EXPECT_EQ(cells, 48u * 48u);
    std::vector<int> part(p->cell_subdomain.begin(), p->cell_subdomain.end());
    EXPECT_EQ(repair_parts(square, part, 0.0), 0) << "every part in one piece, none hinged";
  }
}

// Compact parts (PartitionShape::compact) on a 48 x 48 square in 12 parts: fewer cut facets
// than METIS's own split (kCompactGain), every part in one piece, the counts within
// kCompactImbalance of the mean, counted as taken; the same split again, on one thread or two,
// and METIS's own split with PartitionShape::metis. A strip of 8 x 1 cells in 2 parts, which METIS
// cuts at one facet already: nothing to gain, so METIS's split stays, counted as declined.
TEST(Partition, CompactPartsCutFewerFacets) {
  const Mesh square = quad_strip(48, 48, 1.0, 1.0);
  const auto split = [&](const Mesh& mesh, int k, PartitionShape shape) {
    return partition_mesh(mesh, k, 1, PartitionObjective::volume, ClusterSplit::mesh,
                          kDefaultPartitionSeed, nullptr, 0, shape);
  };
  const auto cut = [](const MeshPartition& p, int nx, int ny) {  // facets between two parts
    int c = 0;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const int e = j * nx + i;
        if (i + 1 < nx) c += p.cell_subdomain[e] != p.cell_subdomain[e + 1];
        if (j + 1 < ny) c += p.cell_subdomain[e] != p.cell_subdomain[e + nx];
      }
    return c;
  };
  const MeshPartition metis = split(square, 12, PartitionShape::metis);
  const MeshPartition compact = split(square, 12, PartitionShape::compact);
  EXPECT_EQ(metis.compact_splits + metis.compact_declined, 0);
  EXPECT_EQ(compact.compact_splits, 1);
  EXPECT_EQ(compact.compact_declined, 0);
  EXPECT_LE(cut(compact, 48, 48), kCompactGain * cut(metis, 48, 48))
      << cut(compact, 48, 48) << " against " << cut(metis, 48, 48);
  EXPECT_EQ(metis.cell_subdomain,
            partition_mesh(square, 12, 1, PartitionObjective::volume, ClusterSplit::mesh,
                           kDefaultPartitionSeed, nullptr, 0, PartitionShape::metis)
                .cell_subdomain);
  ASSERT_EQ(compact.num_subdomains, 12);
  for (const auto& c : compact.subdomain_cells) {
    EXPECT_GE(c.size(), 1u);
    EXPECT_LE(static_cast<double>(c.size()), kCompactImbalance * 48 * 48 / 12);
  }
  std::vector<int> part(compact.cell_subdomain.begin(), compact.cell_subdomain.end());
  EXPECT_EQ(repair_parts(square, part, 0.0), 0) << "every part in one piece, none hinged";
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const MeshPartition one = split(square, 12, PartitionShape::compact);
  omp_set_num_threads(2);
  const MeshPartition two = split(square, 12, PartitionShape::compact);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.cell_subdomain, compact.cell_subdomain);
  EXPECT_EQ(two.cell_subdomain, compact.cell_subdomain);
  const Mesh strip = quad_strip(8, 1, 8.0, 1.0);
  const MeshPartition kept = split(strip, 2, PartitionShape::compact);
  EXPECT_EQ(kept.compact_splits, 0);
  EXPECT_EQ(kept.compact_declined, 1);
  EXPECT_EQ(cut(kept, 8, 1), 1);
  EXPECT_EQ(kept.cell_subdomain, split(strip, 2, PartitionShape::metis).cell_subdomain);
}

// A coefficient jump (cells of x > 0.3 conduct 1e4 times better): with jump_ratio 10 no
// subdomain holds cells of both sides, the two regions get 4 and 8 of the 12 subdomains (their
// shares of the cells, largest remainders), and each subdomain is in one piece. With the ratio
// 0, without the field or with a smooth field (neighbours within the ratio) the split is the
// plain one. Many small regions (single stiff cells) would leave the rest of the mesh too few
// subdomains: the split is declined and counted.
TEST(Partition, NoSubdomainStraddlesACoefficientJump) {
  const Mesh square = quad_strip(48, 48, 1.0, 1.0);
  const int ne = square.num_cells();
  const auto field = [&](const std::function<double(double, double)>& f) {
    std::vector<double> c(ne);
    for (int e = 0; e < ne; ++e) c[e] = f((e % 48 + 0.5) / 48, (e / 48 + 0.5) / 48);
    return c;
  };
  const std::vector<double> jump = field([](double x, double) { return x > 0.3 ? 1e4 : 1.0; });
  const auto split = [&](const std::vector<double>* c, double ratio) {
    return partition_mesh(square, 12, 1, PartitionObjective::volume, ClusterSplit::mesh,
                          kDefaultPartitionSeed, c, ratio);
  };
  const MeshPartition p = split(&jump, kDefaultJumpRatio);
  EXPECT_EQ(p.jump_regions, 2);
  EXPECT_EQ(p.jump_splits_declined, 0);
  int soft = 0, stiff = 0;
  for (const auto& cells : p.subdomain_cells) {
    ASSERT_FALSE(cells.empty());
    const double c0 = jump[cells[0]];
    for (int e : cells) EXPECT_EQ(jump[e], c0) << "a subdomain straddles the jump";
    ++(c0 > 1 ? stiff : soft);
  }
  EXPECT_EQ(soft, 4);  // 14 of 48 columns: 3.5 -> 4 of 12
  EXPECT_EQ(stiff, 8);
  std::vector<int> part(p.cell_subdomain.begin(), p.cell_subdomain.end());
  EXPECT_EQ(repair_parts(square, part, 0.0), 0) << "every part in one piece, none hinged";
  const MeshPartition plain = split(nullptr, 0);
  EXPECT_EQ(split(&jump, 0).cell_subdomain, plain.cell_subdomain);
  const std::vector<double> smooth = field([](double x, double y) { return 1 + 8 * x * y; });
  const MeshPartition s = split(&smooth, kDefaultJumpRatio);
  EXPECT_EQ(s.cell_subdomain, plain.cell_subdomain);
  EXPECT_EQ(s.jump_regions, 0);
  bool straddles = false;  // the plain split does cut through the jump
  for (const auto& cells : plain.subdomain_cells)
    for (int e : cells) straddles = straddles || jump[e] != jump[cells[0]];
  EXPECT_TRUE(straddles);
  std::vector<double> specks(ne, 1.0);
  for (int k = 0; k < 10; ++k) specks[(4 * k + 2) * 48 + 4 * k + 3] = 1e3;
  const MeshPartition d = split(&specks, kDefaultJumpRatio);
  EXPECT_EQ(d.jump_regions, 0);
  EXPECT_EQ(d.jump_splits_declined, 1);
  EXPECT_EQ(d.cell_subdomain, plain.cell_subdomain);
}

// Clusters split from the mesh (ClusterSplit::mesh): the subdomains are numbered cluster-major,
// every cluster holds its share of the subdomains (64 in clusters of 8: 8 each; 30 in clusters
// of 4: 8 clusters of 3 or 4), and each cluster is one compact piece: its cells are joined by
// shared edges, and it touches few other clusters (a square of 64 x 64 cells in 8 clusters).
// Split from the subdomains instead, the clusters are unions of the same subdomains as
// cluster_size = 1 gives.
TEST(Partition, ClustersSplitFromTheMeshAreConnectedAndHoldTheirShare) {
  const Mesh square = quad_strip(64, 64, 1.0, 1.0);
  for (const auto& [subdomains, size] : {std::pair{64, 8}, std::pair{30, 4}}) {
    const MeshPartition p = partition_mesh(square, subdomains, size);
    EXPECT_EQ(p.cluster_split, ClusterSplit::mesh);
    const int clusters = (subdomains + size - 1) / size;
    ASSERT_EQ(p.num_clusters, clusters);
    ASSERT_EQ(p.num_subdomains, subdomains);
    for (int c = 0; c < clusters; ++c) {
      const int members = p.cluster_first[c + 1] - p.cluster_first[c];
      EXPECT_GE(members, subdomains / clusters) << c;
      EXPECT_LE(members, size) << c;
    }
    // The cells of each cluster joined through shared edges: one component per cluster.
    std::vector<int> cluster_of_cell(square.num_cells()), parent(square.num_cells());
    for (int e = 0; e < square.num_cells(); ++e) {
      const int s = p.cell_subdomain[e];
      cluster_of_cell[e] =
          static_cast<int>(std::upper_bound(p.cluster_first.begin(), p.cluster_first.end(), s) -
                           p.cluster_first.begin() - 1);
      parent[e] = e;
    }
    std::function<int(int)> root = [&](int a) {
      return parent[a] == a ? a : parent[a] = root(parent[a]);
    };
    for (int j = 0; j < 64; ++j)
      for (int i = 0; i < 64; ++i) {
        const int e = j * 64 + i;
        for (const int f : {i + 1 < 64 ? e + 1 : -1, j + 1 < 64 ? e + 64 : -1})
          if (f >= 0 && cluster_of_cell[e] == cluster_of_cell[f]) parent[root(e)] = root(f);
      }
    std::set<int> roots;
    for (int e = 0; e < square.num_cells(); ++e) roots.insert(root(e));
    EXPECT_EQ(static_cast<int>(roots.size()), clusters) << subdomains;
  }
  const MeshPartition tfeti = partition_mesh(square, 64, 1);
  const MeshPartition grouped =
      partition_mesh(square, 64, 8, PartitionObjective::automatic, ClusterSplit::subdomains);
  EXPECT_EQ(grouped.cluster_split, ClusterSplit::subdomains);
  // The same subdomains (renumbered cluster-major): cells in one TFETI subdomain stay together.
  std::map<int, int> renamed;
  for (int e = 0; e < square.num_cells(); ++e) {
    const auto [it, fresh] = renamed.insert({tfeti.cell_subdomain[e], grouped.cell_subdomain[e]});
    EXPECT_EQ(it->second, grouped.cell_subdomain[e]) << e;
  }
  EXPECT_EQ(renamed.size(), 64u);
}

TEST(Kernels, RigidBodyMotionsAreTheKernelAndKPlusIsAGeneralizedInverse) {
  for (auto make : {plane_strain_plate, hex8_box}) {
    ProblemSpec spec = make();
    spec.subdomains = spec.mesh_file.empty() ? std::vector<int>{4, 2, 2} : std::vector<int>{8};
    const auto model = make_model(spec);
    Subdomain sd = test::make_subdomain(*model, 1);
    const int expect = model->dim() == 2 ? 3 : 6;
    ASSERT_EQ(sd.kernel_dimension(), expect);
    const Eigen::MatrixXd K(sd.K());
    const Eigen::MatrixXd& R = sd.kernel();
    EXPECT_LT((K * R).norm(), 1e-12 * K.norm());
    EXPECT_LT((R.transpose() * R - Eigen::MatrixXd::Identity(expect, expect)).norm(), 1e-12);
    sd.factorize(Ordering::amd);
    Eigen::MatrixXd KpK(K.rows(), K.cols());
    for (int j = 0; j < K.cols(); ++j) {
      Eigen::VectorXd col = K.col(j);
      sd.apply_pinv(col.data(), KpK.col(j).data());
    }
    EXPECT_LT((K * KpK - K).norm(), 1e-10 * K.norm());  // K K^+ K = K
  }
}

TEST(GmshReader, FormatsAgree) {
  Comm comm;
  if (comm.rank() != 0) return;
  const int threads = omp_get_max_threads();
  omp_set_num_threads(3);  // the Gmsh SDK resets OpenMP's thread count; the reader restores it
  const Mesh a = read_gmsh(kMeshes + "plate-with-hole.msh");
  EXPECT_EQ(omp_get_max_threads(), 3);
  omp_set_num_threads(threads);
  for (const char* f : {"plate-with-hole-22.msh", "plate-with-hole-41bin.msh"}) {
    const Mesh b = read_gmsh(std::string(HTFETI_BINARY_DIR) + "/" + f);
    EXPECT_EQ(a.num_nodes(), b.num_nodes()) << f;
    EXPECT_EQ(a.cells, b.cells) << f;
    EXPECT_LT(std::abs(Eigen::Map<const Eigen::VectorXd>(a.coords.data(), a.coords.size()).sum() -
                       Eigen::Map<const Eigen::VectorXd>(b.coords.data(), b.coords.size()).sum()),
              1e-9);
    for (const auto& [name, nodes] : a.node_groups)
      EXPECT_EQ(nodes, b.node_groups.at(name)) << name;
  }
  EXPECT_EQ(a.dim, 2);
  EXPECT_EQ(a.type, CellType::tri3);
  EXPECT_EQ(a.facet_groups.at("left").facet_nodes, 2);
  EXPECT_GT(a.cell_groups.at("plate").size(), 100u);
}

}  // namespace

namespace {

// A subdomain made of two pieces: the 6 x 2 grid without its middle column of cells.
SubdomainMesh two_pieces() {
  BoxGridOptions o;
  o.dim = 2;
  o.cell = CellType::quad4;
  o.size = {3, 1, 1};
  o.elements = {6, 2, 1};
  SubdomainMesh m = BoxGrid(o).mesh(0);
  std::vector<int> cells;
  for (int e = 0; e < m.num_cells(); ++e)
    if (e % 6 != 2 && e % 6 != 3) cells.insert(cells.end(), &m.cells[4 * e], &m.cells[4 * e] + 4);
  m.cells = cells;
  m.uniform_period = 1;
  return m;
}

}  // namespace

TEST(Kernels, ADisconnectedSubdomainHasAKernelPerPiece) {
  SubdomainMesh m = two_pieces();
  // Nodes of the removed column's interior line are in no cell: drop nothing, they are isolated
  // and would be their own piece; keep only nodes used by cells.
  std::vector<int> used(m.num_nodes(), 0);
  for (int v : m.cells) used[v] = 1;
  std::vector<int> newid(m.num_nodes(), -1);
  SubdomainMesh c = m;
  c.coords.clear();
  c.global_node.clear();
  for (int k = 0, n = 0; k < m.num_nodes(); ++k)
    if (used[k]) {
      newid[k] = n++;
      c.coords.insert(c.coords.end(), &m.coords[3 * k], &m.coords[3 * k] + 3);
      c.global_node.push_back(m.global_node[k]);
    }
  for (int& v : c.cells) v = newid[v];
  for (auto kind : {PhysicsKind::laplace, PhysicsKind::elasticity}) {
    Physics ph;
    ph.kind = kind;
    ph.dim = 2;
    const AssembledSubdomain a = assemble_subdomain(c, ph, {});
    EXPECT_EQ(a.parts, 2);
    ASSERT_EQ(a.R.cols(), 2 * ph.kernel_dimension());
    const Eigen::MatrixXd K(a.K);
    EXPECT_LT((K * a.R).norm(), 1e-12 * K.norm());
    SubdomainSystem sys;
    sys.dofs_per_node = ph.dofs_per_node();
    sys.K = a.K;
    sys.f = Eigen::VectorXd::Zero(a.K.rows());
    sys.R = a.R;
    sys.fixed_dofs = a.fixed_dofs;
    Subdomain sd(sys);
    sd.factorize(Ordering::amd);  // never a singular factorization
    Eigen::MatrixXd KpK(K.rows(), K.cols());
    for (int j = 0; j < K.cols(); ++j) {
      Eigen::VectorXd col = K.col(j);
      sd.apply_pinv(col.data(), KpK.col(j).data());
    }
    EXPECT_LT((K * KpK - K).norm(), 1e-10 * K.norm());
  }
}
