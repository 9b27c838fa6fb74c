// TFETI for the linear problem against the undecomposed solution; runs under mpiexec -n 1, 2, 4.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <filesystem>

#include "helpers.hpp"
#include "htfeti/io/vtu.hpp"
#include "htfeti/solver.hpp"

using namespace htfeti;

namespace {

struct Case {
  int n, ns, m;
  const char* glue;
  ElementKind element;
};

class LinearAgainstUndecomposed : public ::testing::TestWithParam<Case> {};

TEST_P(LinearAgainstUndecomposed, Poisson2d) {
  const Case c = GetParam();
  Comm comm;
  SolveOptions opt;
  opt.decomposition = {ProblemKind::poisson2d, c.element, c.n, c.ns, c.m, parse_glue(c.glue)};
  opt.rtol = 1e-12;
  auto out = solve(opt, comm);
  ASSERT_TRUE(out.converged);
  const auto ref = solve_undecomposed(ProblemKind::poisson2d, c.element, c.n);
  EXPECT_LT(test::relative_error(*out.model, *out.dual, out.u, ref.u), 1e-8);
  const double energy = out.report["objective"];
  EXPECT_NEAR(energy, ref.energy, 1e-8 * std::abs(ref.energy));
  EXPECT_LT(out.report["kkt"]["equality_residual"].get<double>(), 1e-8);
}

INSTANTIATE_TEST_SUITE_P(Tfeti, LinearAgainstUndecomposed,
                         ::testing::Values(Case{8, 2, 1, "averages", ElementKind::q1},
                                           Case{12, 3, 1, "averages", ElementKind::q1},
                                           Case{24, 4, 1, "averages", ElementKind::q1},
                                           Case{16, 8, 1, "averages", ElementKind::p1},
                                           Case{20, 5, 1, "averages", ElementKind::q1}));

INSTANTIATE_TEST_SUITE_P(HTfetiDp, LinearAgainstUndecomposed,
                         ::testing::Values(Case{16, 4, 2, "averages", ElementKind::q1},
                                           Case{24, 6, 3, "averages", ElementKind::q1},
                                           Case{16, 4, 2, "corners", ElementKind::q1},
                                           Case{24, 4, 2, "corners+averages", ElementKind::p1},
                                           Case{32, 8, 4, "averages", ElementKind::q1},
                                           Case{32, 8, 8, "corners", ElementKind::q1}));

}  // namespace

namespace {
// The dataset `name` of an HDF5 file (rows x columns), read serially.
std::vector<double> read_h5(const std::string& file, const char* name, hsize_t dims[2]) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(f, 0) << file;
  const hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
  EXPECT_GE(d, 0) << name;
  const hid_t s = H5Dget_space(d);
  H5Sget_simple_extent_dims(s, dims, nullptr);
  std::vector<double> v(dims[0] * dims[1]);
  H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Sclose(s), H5Dclose(d), H5Fclose(f);
  return v;
}
}  // namespace

// The XDMF output written by all ranks into one HDF5 file (the membranes: contact, 8
// subdomains): /u holds every subdomain's copy of
// its nodes, in subdomain order whatever the number of ranks, so it is the solution's u_i one
// after the other; /points has the same rows. Only the two named files are left.
TEST(XdmfOutput, OneHdf5FileHoldsEverySubdomainsSolution) {
  Comm comm;
  SolveOptions opt;
  opt.decomposition = {ProblemKind::membranes, ElementKind::q1, 16, 2, 1, Glue::averages};
  opt.rtol = 1e-8;
  auto out = solve(opt, comm);
  ASSERT_TRUE(out.converged);
  const std::string dir = ::testing::TempDir() + "xdmf-np" + std::to_string(comm.size());
  if (comm.rank() == 0) std::filesystem::create_directories(dir);
  comm.barrier();
  write_xdmf(dir + "/u.xdmf", *out.model, *out.dual, out.u, out.lambda);
  if (comm.rank() == 0) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/u.xdmf"));
    int files = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
    EXPECT_EQ(files, 2);
  }
  // Every rank reads the whole file and finds its own subdomains' values at their places.
  std::vector<int> mine;
  for (const auto& s : out.dual->subdomains()) mine.push_back(s->id());
  hsize_t dims[2];
  const std::vector<double> u = read_h5(dir + "/u.h5", "u", dims);
  ASSERT_EQ(dims[1], 1u);
  const int nsub = out.model->num_subdomains();
  std::vector<long long> first(nsub + 1, 0);
  for (int s = 0; s < nsub; ++s) first[s + 1] = first[s] + out.model->mesh_counts(s).points;
  ASSERT_EQ(dims[0], static_cast<hsize_t>(first[nsub]));
  double worst = 0;
  for (size_t k = 0; k < mine.size(); ++k) {
    const Eigen::VectorXd& ui = out.u[k];
    ASSERT_EQ(ui.size(), first[mine[k] + 1] - first[mine[k]]);
    for (Eigen::Index j = 0; j < ui.size(); ++j)
      worst = std::max(worst, std::abs(u[first[mine[k]] + j] - ui[j]));
  }
  EXPECT_EQ(worst, 0.0);
  const std::vector<double> xyz = read_h5(dir + "/u.h5", "points", dims);
  EXPECT_EQ(dims[0], static_cast<hsize_t>(first[nsub]));
  EXPECT_EQ(dims[1], 3u);
  comm.barrier();
  if (comm.rank() == 0) std::filesystem::remove_all(dir);
}
