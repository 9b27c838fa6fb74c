#include "htfeti/problem_file.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <stdexcept>

#include "htfeti/expression.hpp"
#include "htfeti/options.hpp"

namespace htfeti {

std::vector<int> parse_int_list(const std::string& text, const std::string& what) {
  std::vector<int> out;
  size_t pos = 0;
  while (true) {
    const size_t comma = text.find(',', pos);
    const std::string item =
        text.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
    int v = 0;
    const auto r = std::from_chars(item.data(), item.data() + item.size(), v);
    if (item.empty() || r.ec != std::errc() || r.ptr != item.data() + item.size() ||
        item[0] == '+' || item[0] == '-')
      throw std::invalid_argument(what + " must be a positive integer or a list like 2,4,2 (got '" +
                                  text + "')");
    if (v <= 0) throw std::invalid_argument(what + " must be positive (got '" + text + "')");
    out.push_back(v);
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return out;
}

namespace {

[[noreturn]] void bad(const std::string& where, const std::string& msg) {
  throw std::invalid_argument("problem file: " + where + ": " + msg);
}

void check_keys(const toml::table& t, const std::string& where,
                std::initializer_list<const char*> allowed) {
  for (auto&& [k, v] : t) {
    const std::string key(k.str());
    if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; })) {
      std::string list;
      for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
      bad(where.empty() ? key : where + "." + key, "unknown key (expected one of: " + list + ")");
    }
  }
}

const toml::table* table_of(const toml::table& root, const char* name, bool required) {
  const toml::node* n = root.get(name);
  if (!n) {
    if (required) bad(std::string("[") + name + "]", "missing table");
    return nullptr;
  }
  if (!n->is_table()) bad(name, "must be a table");
  return n->as_table();
}

double get_double(const toml::table& t, const std::string& where, const char* key, double def,
                  bool required = false) {
  const toml::node* n = t.get(key);
  if (!n) {
    if (required) bad(where + "." + key, "missing");
    return def;
  }
  if (!n->is_number()) bad(where + "." + key, "must be a number");
  const double v = n->value<double>().value();
  if (!std::isfinite(v)) bad(where + "." + key, "must be finite");
  return v;
}

long long get_int(const toml::table& t, const std::string& where, const char* key, long long def) {
  const toml::node* n = t.get(key);
  if (!n) return def;
  if (!n->is_integer()) bad(where + "." + key, "must be an integer");
  return n->value<long long>().value();
}

std::string get_string(const toml::table& t, const std::string& where, const char* key,
                       const std::string& def, bool required = false) {
  const toml::node* n = t.get(key);
  if (!n) {
    if (required) bad(where + "." + key, "missing");
    return def;
  }
  if (!n->is_string()) bad(where + "." + key, "must be a string");
  return n->value<std::string>().value();
}

std::vector<double> get_numbers(const toml::node& n, const std::string& where) {
  std::vector<double> out;
  if (n.is_number()) {
    out.push_back(n.value<double>().value());
  } else if (n.is_array()) {
    for (const auto& e : *n.as_array()) {
      if (!e.is_number()) bad(where, "must be an array of numbers");
      out.push_back(e.value<double>().value());
    }
  } else {
    bad(where, "must be a number or an array of numbers");
  }
  for (double v : out)
    if (!std::isfinite(v)) bad(where, "must be finite");
  return out;
}

// A [solver] or [output] value as the options table reads it (its type checked here).
OptionValue toml_option_value(const OptionSpec& spec, const toml::node& n,
                              const std::string& where) {
  switch (spec.type) {
    case OptionType::boolean:
      if (!n.is_boolean()) bad(where, "must be true or false");
      return n.value<bool>().value();
    case OptionType::integer:
      if (!n.is_integer()) bad(where, "must be an integer");
      return n.value<long long>().value();
    case OptionType::number: {
      if (!n.is_number()) bad(where, "must be a number");
      const double v = n.value<double>().value();
      if (!std::isfinite(v)) bad(where, "must be finite");
      return v;
    }
    case OptionType::choice:
      if (!n.is_string()) bad(where, "must be a string");
      return n.value<std::string>().value();
    case OptionType::path:
      if (n.is_boolean()) return n.value<bool>().value();
      if (!n.is_string()) bad(where, "must be a file name or false");
      return n.value<std::string>().value();
  }
  bad(where, "unknown option type");
}

// decomposition.subdomains entries, range-checked before the cast (4294967300 is not 4).
int subdomain_count(long long v) {
  if (v <= 0 || v > 100000000) bad("decomposition.subdomains", "must be integers from 1 to 1e8");
  return static_cast<int>(v);
}

// A number (written with 17 digits) or an expression in x, y, z (muparser), checked.
std::string number_or_expression(const toml::node& n, const std::string& where) {
  std::string text;
  if (n.is_number()) {
    const double v = n.value<double>().value();
    if (!std::isfinite(v)) bad(where, "must be finite");
    std::ostringstream o;
    o.precision(17);
    o << v;
    text = o.str();
  } else if (n.is_string()) {
    text = n.as_string()->get();
  } else {
    bad(where, "must be a number or an expression string");
  }
  try {
    Expression check(text);
  } catch (const std::invalid_argument& e) {
    bad(where, e.what());
  }
  return text;
}

// [mesh]: a built-in problem (returns true), a mesh file or a generated box.
bool read_mesh(const toml::table& root, const std::string& path, ProblemSpec& spec) {
  const toml::table& mesh = *table_of(root, "mesh", true);
  check_keys(mesh, "mesh",
             {"file", "parts", "generator", "size", "elements", "element", "builtin"});
  if (mesh.contains("builtin")) {
    for (const char* k : {"file", "parts", "generator", "size"})
      if (mesh.contains(k)) bad(std::string("mesh.") + k, "cannot be combined with mesh.builtin");
    for (const char* k : {"physics", "dirichlet", "load", "contact"})
      if (root.contains(k)) bad(k, "a built-in problem defines its own physics and conditions");
    spec.builtin = get_string(mesh, "mesh", "builtin", "");
    auto& o = spec.builtin_options;
    try {
      o.problem = parse_problem(spec.builtin);
      o.element = parse_element(get_string(mesh, "mesh", "element", "q1"));
    } catch (const std::invalid_argument& e) {
      bad("[mesh]", e.what());
    }
    const long long n = get_int(mesh, "mesh", "elements", 128);
    if (n <= 0 || n > 1000000000) bad("mesh.elements", "must be a positive integer");
    o.elements = static_cast<int>(n);
    spec.subdomains = {8};
  } else {
    const bool has_file = mesh.contains("file"), has_gen = mesh.contains("generator"),
               has_parts = mesh.contains("parts");
    if (has_file + has_gen + has_parts != 1)
      bad("[mesh]", "give exactly one of 'file', 'parts' and 'generator'");
    if (has_file || has_parts) {
      const char* key = has_file ? "file" : "parts";
      for (const char* k : {"size", "elements", "element"})
        if (mesh.contains(k)) bad(std::string("mesh.") + k, "is for generator = \"box\" only");
      const std::filesystem::path f = get_string(mesh, "mesh", key, "");
      if (f.empty())
        bad(std::string("mesh.") + key,
            has_file ? "is empty (give the path of a Gmsh mesh)"
                     : "is empty (give the name Gmsh was given with -o when it wrote one file "
                       "per part: NAME.msh for NAME_1.msh ... NAME_N.msh)");
      const std::string resolved =
          f.is_absolute() ? f.string() : (std::filesystem::path(path).parent_path() / f).string();
      (has_file ? spec.mesh_file : spec.mesh_parts) = resolved;
      if (has_parts) spec.subdomains.clear();  // the number of parts, unless given
    } else {
      if (get_string(mesh, "mesh", "generator", "") != "box")
        bad("mesh.generator", "must be \"box\"");
      const std::string el = get_string(mesh, "mesh", "element", "", true);
      try {
        spec.box.cell = parse_cell_type(el);
      } catch (const std::invalid_argument& e) {
        bad("mesh.element", e.what());
      }
      spec.box.dim = cell_dimension(spec.box.cell);
      const toml::node* sz = mesh.get("size");
      if (!sz) bad("mesh.size", "missing");
      const auto size = get_numbers(*sz, "mesh.size");
      if (static_cast<int>(size.size()) != spec.box.dim)
        bad("mesh.size", "must have " + std::to_string(spec.box.dim) + " numbers for " + el);
      const toml::node* ne = mesh.get("elements");
      if (!ne || !ne->is_array()) bad("mesh.elements", "missing, or not an array of integers");
      int d = 0;
      for (const auto& e : *ne->as_array()) {
        if (!e.is_integer() || d >= 3)
          bad("mesh.elements", "must be an array of positive integers");
        const long long v = e.as_integer()->get();  // range-checked before the cast
        if (v <= 0 || v > 1000000000) bad("mesh.elements", "must be integers from 1 to 1e9");
        spec.box.elements[d++] = static_cast<int>(v);
      }
      if (d != spec.box.dim)
        bad("mesh.elements", "must have " + std::to_string(spec.box.dim) + " integers");
      for (int i = 0; i < spec.box.dim; ++i) {
        if (!(size[i] > 0) || size[i] > 1e100) bad("mesh.size", "must lie in (0, 1e100]");
        if (spec.box.elements[i] <= 0) bad("mesh.elements", "must be positive");
        spec.box.size[i] = size[i];
      }
    }
  }
  return !spec.builtin.empty();
}

// [physics]: Laplace (source, coefficient) or elasticity (material, density, gravity).
void read_physics(const toml::table& root, ProblemSpec& spec) {
  const bool has_gen = spec.mesh_file.empty() && spec.mesh_parts.empty();
  // [physics]
  const toml::table& ph = *table_of(root, "physics", true);
  const std::string type = get_string(ph, "physics", "type", "", true);
  try {
    spec.physics.kind = parse_physics(type);
  } catch (const std::invalid_argument& e) {
    bad("physics.type", e.what());
  }
  spec.physics.dim = has_gen ? spec.box.dim : 3;  // set from the mesh later for files
  if (const toml::node* c = ph.get("coefficient"))
    spec.physics.coefficient = number_or_expression(*c, "physics.coefficient");
  if (spec.physics.kind == PhysicsKind::laplace) {
    check_keys(ph, "physics", {"type", "source", "coefficient"});
    if (const toml::node* src = ph.get("source"))
      spec.source = number_or_expression(*src, "physics.source");
  } else {
    check_keys(ph, "physics", {"type", "young", "poisson", "density", "gravity", "coefficient"});
    spec.physics.material.young = get_double(ph, "physics", "young", 0, true);
    spec.physics.material.poisson = get_double(ph, "physics", "poisson", 0, true);
    spec.physics.density = get_double(ph, "physics", "density", 0);
    if (const toml::node* g = ph.get("gravity")) {
      const auto gv = get_numbers(*g, "physics.gravity");
      if (gv.size() < 2 || gv.size() > 3) bad("physics.gravity", "must have 2 or 3 components");
      for (size_t i = 0; i < gv.size(); ++i) spec.physics.gravity[i] = gv[i];
    }
    try {
      Physics p = spec.physics;
      p.dim = 3;
      p.validate();
    } catch (const std::invalid_argument& e) {
      bad("[physics]", e.what());
    }
  }
}

// friction = { law = "tresca", bound = g } or { law = "coulomb", coefficient = mu }.
void read_friction(const toml::node& fn, const std::string& where, ProblemSpec::Contact& c) {
  const std::string fw = where + ".friction";
  if (!fn.is_table())
    bad(fw,
        "must be a table: friction = { law = \"tresca\", bound = ... } or { law = "
        "\"coulomb\", coefficient = ... }");
  const toml::table& ft = *fn.as_table();
  check_keys(ft, fw, {"law", "bound", "coefficient"});
  const std::string law = get_string(ft, fw, "law", "", true);
  if (law == "tresca") {
    if (ft.contains("coefficient")) bad(fw + ".coefficient", "belongs to Coulomb friction");
    if (!ft.contains("bound")) bad(fw + ".bound", "missing (the slip bound, force per area)");
    c.slip_bound = get_double(ft, fw, "bound", 0);
    if (!(c.slip_bound >= 0) || !std::isfinite(c.slip_bound))
      bad(fw + ".bound", "must be a finite number >= 0");
  } else if (law == "coulomb") {
    if (ft.contains("bound")) bad(fw + ".bound", "belongs to Tresca friction");
    if (!ft.contains("coefficient"))
      bad(fw + ".coefficient", "missing (the friction coefficient mu)");
    c.friction_coefficient = get_double(ft, fw, "coefficient", 0);
    if (!(c.friction_coefficient >= 0) || !std::isfinite(c.friction_coefficient))
      bad(fw + ".coefficient", "must be a finite number >= 0");
  } else {
    bad(fw + ".law", "must be \"tresca\" or \"coulomb\"");
  }
}

// [[dirichlet]], [[load]] and [[contact]] on named groups.
void read_conditions(const toml::table& root, ProblemSpec& spec) {
  auto array_of_tables = [&](const char* name) {
    std::vector<const toml::table*> out;
    const toml::node* n = root.get(name);
    if (!n) return out;
    if (!n->is_array_of_tables()) bad(name, std::string("must be written [[") + name + "]]");
    for (const auto& e : *n->as_array()) out.push_back(e.as_table());
    return out;
  };
  const int dofs = spec.physics.kind == PhysicsKind::laplace ? 1 : 3;
  int i = 0;
  for (const toml::table* t : array_of_tables("dirichlet")) {
    const std::string where = "dirichlet #" + std::to_string(++i);
    check_keys(*t, where, {"group", "value", "components"});
    ProblemSpec::Dirichlet d;
    d.group = get_string(*t, where, "group", "", true);
    if (const toml::node* v = t->get("value")) {
      const auto x = get_numbers(*v, where + ".value");
      if (x.size() == 1)
        d.value = {x[0], x[0], x[0]};
      else if (static_cast<int>(x.size()) <= 3 && dofs > 1)
        for (size_t j = 0; j < x.size(); ++j) d.value[j] = x[j];
      else
        bad(where + ".value", "must be one number or one per displacement component");
    }
    if (const toml::node* c = t->get("components")) {
      if (!c->is_array()) bad(where + ".components", "must be an array");
      for (const auto& e : *c->as_array()) {
        int comp = -1;
        if (e.is_integer()) {  // range-checked before the cast (4294967296 is not 0)
          const long long v = e.as_integer()->get();
          comp = v >= 0 && v < dofs ? static_cast<int>(v) : -1;
        }
        if (e.is_string()) {
          const std::string& s = e.as_string()->get();
          comp = s == "x" ? 0 : s == "y" ? 1 : s == "z" ? 2 : -1;
        }
        if (comp < 0 || comp >= dofs)
          bad(where + ".components", "entries must be 0..2 or \"x\", \"y\", \"z\"");
        d.components.push_back(comp);
      }
    }
    spec.dirichlet.push_back(d);
  }
  i = 0;
  for (const toml::table* t : array_of_tables("load")) {
    const std::string where = "load #" + std::to_string(++i);
    check_keys(*t, where, {"group", "traction", "source", "force"});
    ProblemSpec::Load l;
    l.group = get_string(*t, where, "group", "", true);
    const int kinds = t->contains("traction") + t->contains("source") + t->contains("force");
    if (kinds != 1) bad(where, "give exactly one of traction, source, force");
    if (t->contains("source")) {
      l.kind = ProblemSpec::Load::source;
      l.value[0] = get_double(*t, where, "source", 0);
    } else {
      l.kind = t->contains("traction") ? ProblemSpec::Load::traction : ProblemSpec::Load::force;
      const auto x =
          get_numbers(*t->get(l.kind == ProblemSpec::Load::traction ? "traction" : "force"), where);
      if (x.size() > 3) bad(where, "a vector has at most 3 components");
      for (size_t j = 0; j < x.size(); ++j) l.value[j] = x[j];
    }
    spec.loads.push_back(l);
  }
  i = 0;
  for (const toml::table* t : array_of_tables("contact")) {
    const std::string where = "contact #" + std::to_string(++i);
    check_keys(
        *t, where,
        {"group", "master", "search_distance", "multipliers", "direction", "gap", "friction"});
    ProblemSpec::Contact c;
    c.group = get_string(*t, where, "group", "", true);
    // Between two bodies: the slave group against a master group (mortar rows). In elasticity
    // the normal and the gap are the geometry's; a Laplace pair takes a direction (+1: u_slave -
    // u_master <= gap, -1: the other way) and a gap like an obstacle.
    if (t->contains("master")) {
      c.master = get_string(*t, where, "master", "", true);
      if (c.master == c.group) bad(where + ".master", "is the slave group itself");
      if (spec.physics.kind == PhysicsKind::elasticity)
        for (const char* k : {"direction", "gap"})
          if (t->contains(k))
            bad(where + "." + k,
                "does not apply to contact between bodies in elasticity (the normal and the gap "
                "come from the meshes)");
      if (t->contains("search_distance")) {
        c.search_distance = get_double(*t, where, "search_distance", 0);
        if (!(c.search_distance > 0) || !std::isfinite(c.search_distance))
          bad(where + ".search_distance", "must be a finite number > 0");
      }
      if (t->contains("multipliers")) {
        const std::string m = get_string(*t, where, "multipliers", "", true);
        if (m != "dual" && m != "standard")
          bad(where + ".multipliers", "must be \"dual\" or \"standard\", not \"" + m + "\"");
        c.multipliers = m == "dual" ? MortarBasis::dual : MortarBasis::standard;
      }
      if (spec.physics.kind == PhysicsKind::elasticity) {
        if (const toml::node* fn = t->get("friction")) read_friction(*fn, where, c);
        spec.contact.push_back(c);
        continue;
      }
      if (!t->contains("direction")) c.direction = {1, 0, 0};
    } else {
      for (const char* k : {"search_distance", "multipliers"})
        if (t->contains(k)) bad(where + "." + k, "applies to contact between bodies (with master)");
    }
    const toml::node* dn = t->get("direction");
    if (!dn && !c.master.empty()) {
      spec.contact.push_back(c);  // a Laplace pair with the default direction +1 and gap 0
      continue;
    }
    if (!dn) bad(where + ".direction", "missing");
    const auto dir = get_numbers(*dn, where + ".direction");
    if (dir.size() > 3) bad(where + ".direction", "has at most 3 components");
    double norm = 0;
    for (size_t j = 0; j < dir.size(); ++j) c.direction[j] = dir[j], norm += dir[j] * dir[j];
    for (size_t j = dir.size(); j < 3; ++j) c.direction[j] = 0;
    if (!(norm > 0)) bad(where + ".direction", "must not be zero");
    for (double& v : c.direction) v /= std::sqrt(norm);
    const toml::node* g = t->get("gap");
    c.gap = g ? number_or_expression(*g, where + ".gap") : "0";
    if (const toml::node* fn = t->get("friction")) read_friction(*fn, where, c);
    spec.contact.push_back(c);
  }
}

// [decomposition]: subdomains (METIS: N; a generated box: one per axis), cluster_size, glue,
// objective and seed (METIS's).
void read_decomposition(const toml::table& root, ProblemSpec& spec) {
  if (const toml::table* dec = table_of(root, "decomposition", false)) {
    check_keys(*dec, "decomposition",
               {"subdomains", "cluster_size", "glue", "objective", "cluster_split", "seed",
                "jump_ratio", "shape"});
    if (const toml::node* s = dec->get("subdomains")) {
      spec.subdomains.clear();
      if (s->is_integer()) {
        spec.subdomains.push_back(subdomain_count(s->as_integer()->get()));
      } else if (s->is_array()) {
        for (const auto& e : *s->as_array()) {
          if (!e.is_integer()) bad("decomposition.subdomains", "must be integers");
          spec.subdomains.push_back(subdomain_count(e.as_integer()->get()));
        }
      } else {
        bad("decomposition.subdomains", "must be an integer or an array of integers");
      }
      for (int v : spec.subdomains)
        if (v <= 0) bad("decomposition.subdomains", "must be positive");
    }
    const long long m = get_int(*dec, "decomposition", "cluster_size", 1);
    if (m <= 0 || m > 1000000) bad("decomposition.cluster_size", "must be a positive integer");
    spec.cluster_size = static_cast<int>(m);
    // A key whose value is a word of a list (parse: the list's parser, which names the words).
    const auto word = [&](const char* key, const char* fallback, auto parse) {
      try {
        return parse(get_string(*dec, "decomposition", key, fallback));
      } catch (const std::invalid_argument& e) {
        bad(std::string("decomposition.") + key, e.what());
      }
    };
    spec.glue = word("glue", "averages", parse_glue);
    // The keys that steer METIS's split are refused where nothing is split by METIS: a mesh
    // partitioned in advance (mesh.parts) or a box split into boxes (subdomains = [nx, ny, nz]).
    const bool metis = spec.mesh_parts.empty() && spec.subdomains.size() == 1;
    const auto metis_only = [&](const char* key, const char* parts, const char* boxes) {
      if (!metis && dec->contains(key))
        bad(std::string("decomposition.") + key,
            std::string("is for meshes split by METIS (decomposition.subdomains = N); a mesh "
                        "partitioned in advance ") +
                parts + ", a box split into boxes " + boxes);
    };
    metis_only("objective", "keeps its parts", "is not split by METIS");
    spec.partition_objective = word("objective", "auto", parse_partition_objective);
    metis_only("cluster_split", "groups its parts", "has box clusters");
    spec.cluster_split = word("cluster_split", "mesh", parse_cluster_split);
    metis_only("seed", "keeps its parts", "draws nothing");
    const long long seed = get_int(*dec, "decomposition", "seed", kDefaultPartitionSeed);
    if (seed < 0 || seed > 999999999LL)
      bad("decomposition.seed", "must be an integer from 0 to 999999999");
    spec.partition_seed = static_cast<int>(seed);
    metis_only("jump_ratio", "keeps its parts", "cuts along its planes");
    const double ratio = get_double(*dec, "decomposition", "jump_ratio", spec.partition_jump_ratio);
    if (!(ratio == 0 || ratio > 1))
      bad("decomposition.jump_ratio", "must be 0 (off) or a number greater than 1");
    spec.partition_jump_ratio = ratio;
    metis_only("shape", "keeps its parts", "has box parts");
    spec.partition_shape = word("shape", "compact", parse_partition_shape);
  }
}

// [solver] and [output]: generated from the options table (options.hpp).
void read_option_tables(const toml::table& root, RunOptions& run) {
  for (const char* section : {"solver", "output"}) {
    const toml::table* t = table_of(root, section, false);
    if (!t) continue;
    for (auto&& [k, node] : *t) {
      const std::string key(k.str()), where = std::string(section) + "." + key;
      const OptionSpec* spec = find_option(section, key);
      if (!spec) {
        std::string list;
        for (const auto& o : option_table())
          if (std::string(o.section) == section)
            list += (list.empty() ? "" : ", ") + std::string(o.key);
        bad(where, "unknown key (expected one of: " + list + ")");
      }
      set_option(run, *spec, toml_option_value(*spec, node, where), "problem file: " + where);
    }
  }
  try {
    check_option_combinations(run);
  } catch (const std::invalid_argument& e) {
    bad("[solver]", e.what());
  }
}

}  // namespace

ProblemSpec read_problem_file(const std::string& path, RunOptions& run) {
  ProblemSpec spec;
  spec.path = path;
  toml::table root;
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw std::invalid_argument("problem file '" + path + "' is a directory");
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << "problem file '" << path << "': " << e.description() << " (line "
        << e.source().begin.line << ")";
    throw std::invalid_argument(msg.str());
  } catch (const std::exception& e) {
    throw std::invalid_argument("problem file '" + path + "' cannot be read: " + e.what());
  }
  check_keys(
      root, "",
      {"mesh", "physics", "dirichlet", "load", "contact", "decomposition", "solver", "output"});
  if (!read_mesh(root, path, spec)) {
    read_physics(root, spec);
    read_conditions(root, spec);
  }
  read_decomposition(root, spec);
  read_option_tables(root, run);
  return spec;
}

}  // namespace htfeti
