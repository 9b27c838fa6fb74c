// The htfeti program as a user runs it: bad arguments give one message and exit code 2 and leave
// no file behind; reports from 1, 2 and 4 ranks agree to round-off; VTU/PVTU files appear.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

namespace fs = std::filesystem;

namespace {

const std::string bin = HTFETI_BINARY;
const std::string mpiexec = std::string(HTFETI_MPIEXEC) + " " + HTFETI_MPIEXEC_FLAGS;

int run(const std::string& cmd) {
  const int status = std::system((cmd + " > /dev/null 2> cli_stderr.txt").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string stderr_text() {
  std::ifstream f("cli_stderr.txt");
  return std::string(std::istreambuf_iterator<char>(f), {});
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("htfeti_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    fs::current_path(dir);
  }
  void TearDown() override {
    fs::current_path(fs::temp_directory_path());
    fs::remove_all(dir);
  }
  fs::path dir;
};

}  // namespace

TEST_F(Cli, BadArgumentsExitWithCode2AndWriteNothing) {
  const char* bad[] = {"--problem plate",
                       "-n 10 --subdomains 3",
                       "-n -4",
                       "--subdomains 0",
                       "--rtol 1.5",
                       "--rtol 0",
                       "-n 16 --subdomains 4 -m 3",
                       "--glue faces",
                       "--element q2",
                       "--no-such-option",
                       "-n abc",
                       "--beta 1",
                       "--gamma 0",
                       "--rho-factor -1",
                       "--dual-operator dense",
                       "--ordering nd"};
  for (const char* args : bad) {
    EXPECT_EQ(run(bin + " solve " + args + " --report r.json --vtu u.vtu"), 2) << args;
    EXPECT_NE(stderr_text().find("error"), std::string::npos) << args;
    EXPECT_FALSE(fs::exists("r.json")) << args;
    EXPECT_FALSE(fs::exists("u.vtu")) << args;
  }
  EXPECT_EQ(run(bin + " spectrum -m 3 -n 64"), 2);
  EXPECT_EQ(run(bin), 2);  // a subcommand is required
  EXPECT_EQ(run(bin + " solve --help"), 0);
}

TEST_F(Cli, ReportsDoNotDependOnTheNumberOfRanks) {
  nlohmann::json reports[3];
  const int ranks[3] = {1, 2, 4};
  for (int i = 0; i < 3; ++i) {
    const std::string out = "r" + std::to_string(ranks[i]) + ".json";
    ASSERT_EQ(run(mpiexec + " -n " + std::to_string(ranks[i]) + " " + bin +
                  " solve --problem membranes -n 32 --subdomains 4 -m 2 --rtol 1e-8 --report " +
                  out + " --vtu u" + std::to_string(ranks[i]) + ".vtu"),
              0);
    std::ifstream f(out);
    reports[i] = nlohmann::json::parse(f);
  }
  EXPECT_TRUE(fs::exists("u1.vtu"));
  EXPECT_TRUE(fs::exists("u2.pvtu") && fs::exists("u2_0.vtu") && fs::exists("u2_1.vtu"));
  EXPECT_TRUE(fs::exists("u4.pvtu") && fs::exists("u4_3.vtu"));
  for (int i = 1; i < 3; ++i) {
    const auto &a = reports[0], &b = reports[i];
    EXPECT_EQ(b["ranks"].get<int>(), ranks[i]);
    const double ea = a["objective"], eb = b["objective"];
    EXPECT_NEAR(eb, ea, 1e-10 * std::abs(ea));
    for (const char* key :
         {"dual_dimension", "equalities", "inequalities", "coarse_dimension", "primal_dimension"})
      EXPECT_EQ(a[key], b[key]) << key;
    for (size_t j = 0; j < a["contact"]["y"].size(); ++j) {
      EXPECT_NEAR(b["contact"]["u_left"][j].get<double>(), a["contact"]["u_left"][j].get<double>(),
                  1e-9);
      EXPECT_NEAR(b["contact"]["multiplier"][j].get<double>(),
                  a["contact"]["multiplier"][j].get<double>(), 1e-9);
    }
  }
  for (const char* key : {"problem",
                          "elements",
                          "subdomains",
                          "clusters",
                          "cluster_size",
                          "primal_dimension",
                          "dual_dimension",
                          "equalities",
                          "inequalities",
                          "coarse_dimension",
                          "ranks",
                          "threads",
                          "converged",
                          "outer_iterations",
                          "inner_iterations",
                          "matvecs",
                          "objective",
                          "kkt",
                          "timings",
                          "contact"})
    EXPECT_TRUE(reports[0].contains(key)) << key;
  for (const char* key :
       {"equality_residual", "max_violation", "min_multiplier", "complementarity"})
    EXPECT_TRUE(reports[0]["kkt"].contains(key)) << key;
  for (const char* key : {"setup", "factorization", "coarse_problem", "solve", "reconstruction"})
    EXPECT_TRUE(reports[0]["timings"].contains(key)) << key;
}

TEST_F(Cli, ReportsDoNotDependOnTheNumberOfThreads) {
  // -m 3: four clusters per rank, threads run over clusters; -m 6: one cluster per rank, threads
  // run over the subdomains inside it. Both with the explicit and the implicit operator.
  for (const char* config :
       {"-m 3", "-m 6", "-m 3 --dual-operator implicit", "-m 6 --dual-operator implicit"}) {
    nlohmann::json reports[2];
    for (int t = 1; t <= 2; ++t) {
      const std::string out = "t" + std::to_string(t) + ".json";
      ASSERT_EQ(run("OMP_NUM_THREADS=" + std::to_string(t) + " " + mpiexec + " -n 2 " + bin +
                    " solve --problem membranes -n 48 --subdomains 6 --rtol 1e-8 --no-vtu " +
                    config + " --report " + out),
                0)
          << config;
      std::ifstream f(out);
      reports[t - 1] = nlohmann::json::parse(f);
    }
    EXPECT_EQ(reports[0]["threads"].get<int>(), 1);
    EXPECT_EQ(reports[1]["threads"].get<int>(), 2);
    const double e1 = reports[0]["objective"], e2 = reports[1]["objective"];
    EXPECT_NEAR(e2, e1, 1e-12 * std::abs(e1)) << config;
    // Sums are formed in a fixed order: the iteration history is the same, not only close.
    EXPECT_EQ(reports[0]["matvecs"], reports[1]["matvecs"]) << config;
    EXPECT_EQ(reports[0]["outer_iterations"], reports[1]["outer_iterations"]) << config;
  }
}
