// The options table (options.hpp): every option has one row with a problem-file key, a flag and
// help; the problem-file reader, the command-line reader and the report's echo all agree on the
// values; validate_solver() refuses what a row refuses.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "htfeti/options.hpp"
#include "htfeti/problem_file.hpp"

using namespace htfeti;
namespace fs = std::filesystem;

namespace {

const char* kBox =
    "[mesh]\ngenerator = \"box\"\nsize = [1.0, 1.0]\nelements = [8, 8]\nelement = \"quad4\"\n"
    "[physics]\ntype = \"laplace\"\nsource = 1.0\n[[dirichlet]]\ngroup = \"x0\"\nvalue = 0.0\n"
    "[decomposition]\nsubdomains = [2, 2]\n";

RunOptions read_with(const std::string& tables) {
  const fs::path p =
      fs::temp_directory_path() / ("htfeti_options_" + std::to_string(::getpid()) + ".toml");
  std::ofstream(p) << kBox << tables;
  RunOptions run;
  try {
    read_problem_file(p.string(), run);
  } catch (...) {
    fs::remove(p);
    throw;
  }
  fs::remove(p);
  return run;
}

// A value of each row other than its default, written as on the command line.
std::string other_value(const OptionSpec& o, const nlohmann::json& def) {
  switch (o.type) {
    case OptionType::boolean:
      return def.get<bool>() ? "false" : "true";
    case OptionType::integer:
      return def.get<long long>() == 1 ? "2" : "1";
    case OptionType::number:
      for (const char* c : {"0.5", "1.5", "3.0", "1e-4"}) {  // the first the row accepts
        RunOptions scratch;
        try {
          o.set(scratch, parse_option_text(o, c));
        } catch (const std::invalid_argument&) {
          continue;
        }
        if (def.is_null() || def.get<double>() != std::stod(c)) return c;
      }
      return "";
    case OptionType::choice:
      for (const auto& c : o.choices)
        if (c != def.get<std::string>()) return c;
      return o.choices.front();
    case OptionType::path:
      return std::string(o.key) + "-other.out";
  }
  return "";
}

}  // namespace

TEST(Options, EveryRowHasAKeyAFlagAndHelpOnce) {
  std::set<std::string> keys, flags;
  const RunOptions defaults;
  for (const auto& o : option_table()) {
    const std::string section = o.section;
    EXPECT_TRUE(section == "solver" || section == "output") << o.key;
    EXPECT_TRUE(keys.insert(section + "." + o.key).second) << o.key;
    EXPECT_TRUE(*o.flag || *o.negative_flag) << o.key << " has no command-line flag";
    for (const char* f : {o.flag, o.negative_flag})
      if (*f) EXPECT_TRUE(flags.insert(f).second) << f;
    EXPECT_GT(std::string(o.help).size(), 10u) << o.key;
    EXPECT_EQ(find_option(o.section, o.key), &o);
    EXPECT_EQ(o.type == OptionType::choice, !o.choices.empty()) << o.key;
    // Memory is in one unit.
    if (std::string(o.key).find("_gb") != std::string::npos) EXPECT_STREQ(o.unit, "GB") << o.key;
    EXPECT_NO_THROW(o.get(defaults)) << o.key;
  }
  EXPECT_EQ(find_option("solver", "no_such_key"), nullptr);
}

// The echo of the options, read back as a problem file, gives the same options: for the
// defaults, and with every option moved off its default at once.
TEST(Options, EchoReadsBackAsTheSameOptions) {
  const RunOptions defaults;
  EXPECT_EQ(options_json(read_with(options_toml(defaults))), options_json(defaults));
  RunOptions changed;
  for (const auto& o : option_table()) {
    if (std::string(o.key) == "release_factors") continue;  // contradicts keep_factors = true
    const std::string text = other_value(o, o.get(defaults));
    set_option(changed, o, parse_option_text(o, text), o.flag);
  }
  const nlohmann::json echo = options_json(changed);
  for (const auto& o : option_table())
    if (std::string(o.key) != "release_factors")
      EXPECT_NE(echo[o.section][o.key], options_json(defaults)[o.section][o.key]) << o.key;
  EXPECT_EQ(options_json(read_with(options_toml(changed))), echo);
}

// The command line and the problem file read a value the same way, and refuse the same values.
TEST(Options, CommandLineAndFileAgree) {
  const RunOptions defaults;
  for (const auto& o : option_table()) {
    if (o.type == OptionType::boolean || o.type == OptionType::path) continue;
    const std::string text = other_value(o, o.get(defaults));
    RunOptions cli;
    set_option(cli, o, parse_option_text(o, text), o.flag);
    const std::string toml_value = o.type == OptionType::choice ? "\"" + text + "\"" : text;
    const RunOptions file =
        read_with("[" + std::string(o.section) + "]\n" + o.key + " = " + toml_value + "\n");
    EXPECT_EQ(o.get(cli), o.get(file)) << o.key;
  }
  const auto* rtol = find_option("solver", "rtol");
  for (const char* bad : {"nan", "inf", "1.5", "0", "-1e-4", "1e-4x", ""}) {
    RunOptions run;
    EXPECT_THROW(set_option(run, *rtol, parse_option_text(*rtol, bad), "--rtol"),
                 std::invalid_argument)
        << bad;
  }
  for (const char* bad :
       {"rtol = 1.5", "rtol = nan", "rtol = \"1e-4\"", "max_iterations = -1",
        "max_iterations = 4294967296", "coarse_steps_per_product = 3", "memory_limit_gb = 0.0",
        "numeric_cache_gb = -1.0", "dual_operator = \"dense\"", "keep_factors = 1", "no_such = 1",
        "keep_factors = true\nrelease_factors = true"})
    EXPECT_THROW(read_with(std::string("[solver]\n") + bad + "\n"), std::invalid_argument) << bad;
  for (const char* bad : {"report = true", "vtu = 3", "vtu_io = \"fast\"", "report = \"\""})
    EXPECT_THROW(read_with(std::string("[output]\n") + bad + "\n"), std::invalid_argument) << bad;
  for (const char* bad : {"0x10", " 16", "+3", "-2", "1e3", "99999999999999999999"})
    EXPECT_THROW(parse_option_text(*find_option("solver", "max_iterations"), bad),
                 std::invalid_argument)
        << bad;
}

// validate_solver() checks a SolveOptions built in code by the same rows.
TEST(Options, ValidateSolverUsesTheTable) {
  SolveOptions o;
  EXPECT_NO_THROW(validate_solver(o));
  o.rtol = 2;
  EXPECT_THROW(validate_solver(o), std::invalid_argument);
  o = SolveOptions{};
  o.smalbe.beta = 1;
  EXPECT_THROW(validate_solver(o), std::invalid_argument);
  o = SolveOptions{};
  o.feti.memory_limit_mb = std::nan("");
  EXPECT_THROW(validate_solver(o), std::invalid_argument);
  o = SolveOptions{};
  o.feti.keep_factors = true;
  o.feti.factor_budget_bytes = 0;
  EXPECT_THROW(validate_solver(o), std::invalid_argument);
}
