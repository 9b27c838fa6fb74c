// The options of a solve, declared once (docs/architecture.md, "Options"): each row of
// option_table() gives an option's problem-file key (in [solver] or [output]), its command-line
// flag, its unit, its help text and how its value is read, checked and echoed. The command line
// (apps/htfeti.cpp), the problem-file reader (problem_file.cpp), validate_solver(), the report's
// `options` block and `htfeti solve --dry-run` are all generated from this table; the defaults
// are the member initializers of SolveOptions and OutputOptions, which the table reads back.
//
// Adding an option: a member in SolveOptions (or FetiOptions, SmalbeOptions, OutputOptions) with
// its default, and one row in option_table() (src/options.cpp). Nothing else.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "htfeti/io/vtu.hpp"
#include "htfeti/solver.hpp"

namespace htfeti {

/// Where the outputs go (the [output] table of a problem file).
struct OutputOptions {
  std::string report = "htfeti-report.json";
  std::string vtu = "htfeti-solution.vtu";
  std::string xdmf;  ///< XDMF + HDF5 output (none by default)
  bool write_report = true;
  bool write_vtu = true;
  bool write_xdmf = false;
  bool vtu_ascii = false;
  VtuIo vtu_io = VtuIo::automatic;
};

struct OptionSpec;

/// Everything `htfeti solve` takes besides the problem itself.
struct RunOptions {
  SolveOptions solve;
  OutputOptions output;
  /// The options set by the problem file or the command line (set_option), in the order first
  /// given: rows of option_table().
  std::vector<const OptionSpec*> given;
  /// The [decomposition] keys that act only with clusters of several subdomains ("glue",
  /// "cluster_split") whose values, after the problem file and the flags, are not the
  /// defaults (each once), for unused_options().
  std::vector<std::string> given_decomposition;
};

/// How an option's value is written: a switch (true/false; on the command line a flag), an
/// integer, a number, a word of a fixed list, or a file name that `false` (or the `--no-` flag)
/// turns off.
enum class OptionType { boolean, integer, number, choice, path };

/// A value as read from a problem file or the command line, before it is checked.
using OptionValue = std::variant<bool, long long, double, std::string>;

/// The runs an option takes effect in. An option given a value other than its default for a
/// run outside its scope is named by unused_options() (a warning and the report's
/// `unused_options`): the value was read and checked, and changed nothing.
enum class OptionScope {
  every_run,
  contact,             ///< SMALBE-M: problems with contact (inequality) rows
  coulomb,             ///< Coulomb friction's fixed point
  pcg,                 ///< PCG: problems without contact rows
  preconditioned,      ///< a preconditioner is built
  dirichlet,           ///< the Dirichlet preconditioner
  explicit_operator,   ///< the explicit dual operator
  automatic_operator,  ///< --dual-operator auto decides (its explicit_budget_gb)
  vtu_output,          ///< the VTU output is written
};

struct OptionSpec {
  const char* section;  ///< "solver" or "output": the problem-file table
  const char* key;      ///< the problem-file key, and the report's name
  const char* flag;     ///< the command-line flag ("" for none); may carry a short alias
  /// A flag that sets the value false (a switch), or turns a path off ("" for none).
  const char* negative_flag;
  OptionType type;
  const char* unit;  ///< "GB", "" ...
  const char* help;
  std::vector<std::string> choices;  ///< OptionType::choice: the accepted words
  /// Checks and stores a value; throws std::invalid_argument with a message that does not
  /// repeat the option's name (the caller prefixes the key or the flag).
  std::function<void(RunOptions&, const OptionValue&)> set;
  /// The value in effect, for the report and the dry run (null: "none", e.g. no memory limit).
  std::function<nlohmann::json(const RunOptions&)> get;
  OptionScope scope = OptionScope::every_run;
};

/// Every option of a solve, in the order the help lists them.
const std::vector<OptionSpec>& option_table();

/// The row whose problem-file key is `key` in `section` (nullptr if none).
const OptionSpec* find_option(const std::string& section, const std::string& key);

/// Reads a command-line value (the text after the flag) as the option's type, strictly: whole
/// decimal integers, finite numbers, words of the list. Throws std::invalid_argument.
OptionValue parse_option_text(const OptionSpec& spec, const std::string& text);

/// set() with the message prefixed by `where` ("--rtol", "problem file: solver.rtol").
void set_option(RunOptions& run, const OptionSpec& spec, const OptionValue& value,
                const std::string& where);

/// An option given for a run it does not act in: its key ("solver.rho_factor"), its flag, why.
struct UnusedOption {
  std::string key, flag, reason;
};

/// The options of run.given, set to other than their defaults, that the solve described by
/// `report` (its solver.algorithm, solver.coulomb, preconditioner and dual_operator) did not use;
/// and the keys of run.given_decomposition when every cluster is one subdomain (the report's
/// clusters equal to its subdomains: TFETI).
std::vector<UnusedOption> unused_options(const RunOptions& run, const nlohmann::json& report);

/// Checks what one option cannot: combinations (keep_factors with release_factors).
void check_option_combinations(const RunOptions& run);

/// Every option in effect: {"solver": {key: value, ...}, "output": {...}}.
nlohmann::json options_json(const RunOptions& run);

/// The options as `[solver]` and `[output]` tables of a problem file (values that are null, such
/// as no memory limit, as comments).
std::string options_toml(const RunOptions& run);

}  // namespace htfeti
