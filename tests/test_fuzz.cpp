// Fuzz test of the readers (problem file: toml++ and our checks; mesh: the Gmsh SDK and our
// checks), as the reliability issue asks: a bounded, reproducible set of mutated inputs (fixed
// seed), each run through `htfeti solve`. Every run must end through a documented exit code
// (0 solved, 2 bad input, 3 not converged, 4 numerical failure, 5 not finite) with a message
// for the non-zero ones: never a signal, never exit 1 (internal error), and an input error leaves
// no output file. The seeds are a tiny triangle mesh of the unit square
// (tests/meshes/fuzz-square.geo, written by the gmsh program at build time) and a plane-strain
// contact problem on it.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const std::string bin = HTFETI_BINARY;

const char* kSeedProblem = R"([mesh]
file = "mesh.msh"

[physics]
type = "elasticity"
young = 1000.0
poisson = 0.3

[[dirichlet]]
group = "left"
value = [0.0, 0.0]

[[load]]
group = "square"
force = [0.0, -2.0]

[[contact]]
group = "right"
direction = [1.0, 0.0]
gap = "0.001 + 0.01*y"

[decomposition]
subdomains = 2

[solver]
rtol = 1e-6
max_iterations = 300
)";

std::string read(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void write(const fs::path& p, const std::string& s) {
  std::ofstream f(p, std::ios::binary);
  f << s;
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& l : v) s += l + "\n";
  return s;
}

// One random edit: delete / duplicate / swap lines, delete or insert a character, truncate, or
// replace a number by a hostile one.
std::string mutate(const std::string& text, std::mt19937& rng) {
  static const std::vector<std::string> numbers = {
      "0", "-1", "-0", "1e308", "-1e308", "nan", "inf", "1e-300", "2147483648", "99999999999",
      "3.5", "\"x\"", "[]", "true", "", "0x10",
      // integers that wrap to small ones in 32 bits, an overflow of the data, a vector with a
      // component the problem does not have
      "4294967296", "4294967298", "1e200", "[0.0, 0.0, -1.0]"};
  static const std::string chars = "=[]\"{},.#\n -$e";
  auto pick = [&](size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(rng); };
  std::vector<std::string> L = lines_of(text);
  std::string s = text;
  switch (pick(8)) {
    case 7: {  // swap two numbers of one line (in a mesh: invert or twist an element)
      const size_t i = pick(L.size());
      std::vector<std::string> w;
      std::stringstream in(L[i]);
      for (std::string t; in >> t;) w.push_back(t);
      if (w.size() < 2) return text;
      std::swap(w[pick(w.size())], w[pick(w.size())]);
      std::string line;
      for (const auto& t : w) line += (line.empty() ? "" : " ") + t;
      L[i] = line;
      return join(L);
    }
    case 0:  // delete a line
      L.erase(L.begin() + static_cast<long>(pick(L.size())));
      return join(L);
    case 1: {  // duplicate a line
      const size_t i = pick(L.size());
      L.insert(L.begin() + static_cast<long>(i), L[i]);
      return join(L);
    }
    case 2:  // swap two lines
      std::swap(L[pick(L.size())], L[pick(L.size())]);
      return join(L);
    case 3:  // delete a character
      s.erase(pick(s.size()), 1);
      return s;
    case 4:  // insert a character
      s.insert(pick(s.size()), 1, chars[pick(chars.size())]);
      return s;
    case 5:  // truncate
      return s.substr(0, pick(s.size()));
    default: {  // replace the k-th number
      std::vector<std::pair<size_t, size_t>> spans;
      for (size_t i = 0; i < s.size();) {
        if (std::isdigit(static_cast<unsigned char>(s[i]))) {
          size_t j = i;
          while (j < s.size() && (std::isalnum(static_cast<unsigned char>(s[j])) || s[j] == '.' ||
                                  s[j] == '-' || s[j] == '+'))
            ++j;
          spans.push_back({i, j - i});
          i = j;
        } else {
          ++i;
        }
      }
      if (spans.empty()) return s;
      const auto [at, len] = spans[pick(spans.size())];
      return s.substr(0, at) + numbers[pick(numbers.size())] + s.substr(at + len);
    }
  }
}

struct Outcome {
  int code;  // exit status, or -signal
  std::string err;
};

Outcome run(const std::string& args) {
  const int status =
      std::system((bin + " solve " + args + " > out.txt 2> err.txt < /dev/null").c_str());
  Outcome o{WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status), read("err.txt")};
  return o;
}

class Fuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("htfeti_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    fs::current_path(dir);
    mesh = read(HTFETI_FUZZ_MESH);
    ASSERT_FALSE(mesh.empty());
  }
  void TearDown() override {
    fs::current_path(fs::temp_directory_path());
    fs::remove_all(dir);
  }
  // Runs the case; checks the outcome; counts it by exit code.
  void check(const std::string& what, int i) {
    fs::remove("r.json");
    const Outcome o = run("p.toml --report r.json --no-vtu");
    ++codes[o.code];
    const std::string tag = what + " mutation " + std::to_string(i);
    EXPECT_TRUE(o.code == 0 || o.code == 2 || o.code == 3 || o.code == 4 || o.code == 5)
        << tag << ": exit " << o.code << "\n"
        << o.err << "\ninput kept as " << keep(tag);
    if (o.code != 0) EXPECT_NE(o.err.find("error"), std::string::npos) << tag << ": " << o.err;
    if (o.code == 2) EXPECT_FALSE(fs::exists("r.json")) << tag;
    if (o.code == 3) EXPECT_TRUE(fs::exists("r.json")) << tag;  // not converged: a report
  }
  std::string keep(const std::string& tag) {
    const fs::path to =
        fs::temp_directory_path() / ("htfeti-fuzz-failure-" + std::to_string(++kept));
    fs::create_directories(to);
    fs::copy_file("p.toml", to / "p.toml", fs::copy_options::overwrite_existing);
    fs::copy_file("mesh.msh", to / "mesh.msh", fs::copy_options::overwrite_existing);
    return to.string() + " (" + tag + ")";
  }
  // 60 inputs, each the seed with 1-3 random edits, written to `file` and run.
  void run_mutations(const std::string& what, const std::string& file, const std::string& seed,
                     unsigned rng_seed) {
    std::mt19937 rng(rng_seed);
    for (int i = 0; i < 60; ++i) {
      std::string text = seed;
      const int edits = 1 + static_cast<int>(rng() % 3);
      for (int e = 0; e < edits; ++e) text = mutate(text, rng);
      write(file, text);
      check(what, i);
    }
    std::string summary;
    for (const auto& [c, n] : codes)
      summary += " exit " + std::to_string(c) + ": " + std::to_string(n);
    std::printf("%s fuzz:%s\n", what.c_str(), summary.c_str());
    EXPECT_GT(codes[2], 0);  // the mutations do reach the input checks
  }
  fs::path dir;
  std::string mesh;
  std::map<int, int> codes;
  int kept = 0;
};

}  // namespace

TEST_F(Fuzz, SeedsSolve) {
  write("mesh.msh", mesh);
  write("p.toml", kSeedProblem);
  const Outcome o = run("p.toml --report r.json --no-vtu");
  ASSERT_EQ(o.code, 0) << o.err;
}

TEST_F(Fuzz, MutatedProblemFilesEndInDocumentedExits) {
  write("mesh.msh", mesh);
  run_mutations("problem file", "p.toml", kSeedProblem, 20261122);
}

TEST_F(Fuzz, MutatedMeshFilesEndInDocumentedExits) {
  write("p.toml", kSeedProblem);
  run_mutations("mesh file", "mesh.msh", mesh, 1122);
}
