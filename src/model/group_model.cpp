// The model of a ProblemSpec (problem_spec.hpp): conditions on named groups, on a mesh source.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/expression.hpp"
#include "htfeti/fem/physics.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/mesh/mesh.hpp"
#include "htfeti/model/contact_pairs.hpp"
#include "htfeti/model/problem_spec.hpp"
#include "htfeti/partition/partition.hpp"
#include "mesh_source.hpp"
#include "pack.hpp"

namespace htfeti {

void check_cells(const Mesh& mesh, const std::string& file) {
  const int nc = cell_nodes(mesh.type);
  double x[24];
  for (int e = 0; e < mesh.num_cells(); ++e) {
    const int* cn = mesh.cells.data() + static_cast<size_t>(e) * nc;
    for (int a = 0; a < nc; ++a)
      for (int d = 0; d < 3; ++d) x[3 * a + d] = mesh.coords[3 * static_cast<size_t>(cn[a]) + d];
    if (!cell_is_valid(mesh.type, x))
      throw std::invalid_argument(
          "mesh file '" + file + "': element " +
          std::to_string(e < static_cast<int>(mesh.cell_tags.size()) ? mesh.cell_tags[e] : e) +
          " (" + to_string(mesh.type) +
          ") is inverted, self-intersecting or degenerate (its Jacobian changes sign or "
          "vanishes)");
  }
}

namespace {

std::string list_groups(const std::set<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "(none)" : s;
}

std::string point_text(const std::array<double, 3>& p) {
  std::ostringstream o;
  o.precision(6);
  o << p[0] << ", " << p[1] << ", " << p[2];
  return o.str();
}

// A generated box split into boxes of subdomains: decomposition.subdomains = [sx, sy(, sz)].
class BoxSplit final : public MeshSource {
 public:
  explicit BoxSplit(const ProblemSpec& spec) {
    if (static_cast<int>(spec.subdomains.size()) != spec.box.dim)
      throw std::invalid_argument("decomposition.subdomains must have " +
                                  std::to_string(spec.box.dim) + " numbers for a " +
                                  std::to_string(spec.box.dim) + "D box (or one for METIS)");
    BoxGridOptions o = spec.box;
    for (int d = 0; d < o.dim; ++d) o.subdomains[d] = spec.subdomains[d];
    o.cluster_size = spec.cluster_size;
    grid_ = std::make_unique<BoxGrid>(o);
    if (spec.glue != Glue::corners && spec.cluster_size > 1)
      for (int d = 0; d < o.dim; ++d)
        if (grid_->H(d) < 2)
          throw std::invalid_argument(
              "gluing by averages needs at least 2 elements per subdomain side; use glue = "
              "\"corners\" or fewer subdomains");
  }
  int dim() const override { return grid_->dim(); }
  int num_subdomains() const override { return static_cast<int>(grid_->num_subdomains()); }
  int num_clusters() const override { return static_cast<int>(grid_->num_clusters()); }
  int cluster_first(int c) const override { return c * grid_->subdomains_per_cluster(); }
  long long num_nodes() const override { return grid_->num_nodes(); }
  long long subdomain_nodes() const override {
    return grid_->num_subdomains() * grid_->nodes_per_subdomain();
  }
  SubdomainMesh mesh(int s) const override { return grid_->mesh(s); }
  bool mesh_counts(int, Model::MeshCounts& counts) const override {
    counts = box_mesh_counts(*grid_);
    return true;
  }
  void groups(std::set<std::string>& nodes, std::set<std::string>& facets,
              std::set<std::string>&) const override {
    static const char* faces[6] = {"x0", "x1", "y0", "y1", "z0", "z1"};
    for (int i = 0; i < 2 * grid_->dim(); ++i) nodes.insert(faces[i]), facets.insert(faces[i]);
  }
  void describe(const ProblemSpec& spec, nlohmann::json& j) const override {
    j["mesh"] = box_description(spec);
    j["partitioner"] = "box";
    j["subdomains_per_axis"] = std::vector<int>(spec.subdomains.begin(), spec.subdomains.end());
    j["H_over_h"] = grid_->H(0);
  }
  Model::MeshCounts held() const override { return {}; }
  static nlohmann::json box_description(const ProblemSpec& spec) {
    const auto& b = spec.box;
    return {{"generator", "box"},
            {"element", to_string(b.cell)},
            {"size", std::vector<double>(b.size.begin(), b.size.begin() + b.dim)},
            {"elements", std::vector<int>(b.elements.begin(), b.elements.begin() + b.dim)}};
  }

 private:
  std::unique_ptr<BoxGrid> grid_;
};

// A whole mesh split by METIS: decomposition.subdomains = N. The mesh is the file's, or a
// generated box made whole.
class MetisSplit final : public MeshSource {
 public:
  explicit MetisSplit(const ProblemSpec& spec) {
    if (!spec.mesh_file.empty()) {
      mesh_ = std::make_unique<Mesh>(read_gmsh(spec.mesh_file));
      check_cells(*mesh_, spec.mesh_file);
    } else {  // a generated box split by METIS: generate it whole
      BoxGridOptions o = spec.box;
      o.subdomains = {1, 1, 1};
      o.cluster_size = 1;
      const SubdomainMesh whole = BoxGrid(o).mesh(0);
      mesh_ = std::make_unique<Mesh>();
      mesh_->dim = whole.dim;
      mesh_->type = whole.type;
      mesh_->coords = whole.coords;
      mesh_->cells = whole.cells;
      mesh_->node_groups = whole.node_groups;
      for (const auto& [name, fg] : whole.facet_groups)
        mesh_->facet_groups[name] = {fg.facet_nodes, fg.nodes};
    }
  }
  // Split after the physics was checked (the dimension comes from the mesh). With a coefficient
  // field, its values at the cells' centroids (as the assembly takes them) keep the subdomains
  // off its jumps (partition.hpp).
  void split(const ProblemSpec& spec, const Physics& physics) {
    const double t0 = seconds_now();
    std::vector<double> coefficient;
    if (!physics.coefficient.empty() && spec.partition_jump_ratio > 0) {
      const Expression field(physics.coefficient);
      const int ne = mesh_->num_cells(), nc = cell_nodes(mesh_->type);
      coefficient.resize(ne);
      for (int e = 0; e < ne; ++e)
        coefficient[e] = cell_coefficient(field, mesh_->type, mesh_->coords,
                                          mesh_->cells.data() + static_cast<size_t>(e) * nc);
    }
    part_ = std::make_unique<MeshPartition>(partition_mesh(
        *mesh_, spec.subdomains.at(0), spec.cluster_size, spec.partition_objective,
        spec.cluster_split, spec.partition_seed, coefficient.empty() ? nullptr : &coefficient,
        spec.partition_jump_ratio, spec.partition_shape));
    part_->seconds = seconds_now() - t0;
  }
  int dim() const override { return mesh_->dim; }
  int num_subdomains() const override { return part_->num_subdomains; }
  int num_clusters() const override { return part_->num_clusters; }
  int cluster_first(int c) const override { return part_->cluster_first[c]; }
  long long num_nodes() const override { return mesh_->num_nodes(); }
  long long subdomain_nodes() const override {
    return static_cast<long long>(part_->copy_list.size());
  }
  SubdomainMesh mesh(int s) const override { return extract_subdomain(*mesh_, *part_, s); }
  bool mesh_counts(int, Model::MeshCounts&) const override { return false; }
  void groups(std::set<std::string>& nodes, std::set<std::string>& facets,
              std::set<std::string>& cells) const override {
    for (const auto& [n, v] : mesh_->node_groups) nodes.insert(n);
    for (const auto& [n, v] : mesh_->facet_groups) facets.insert(n);
    for (const auto& [n, v] : mesh_->cell_groups) cells.insert(n);
  }
  bool contact_surfaces(const ProblemSpec& spec, const Physics& physics,
                        ContactSurfaces& out) const override {
    out = htfeti::contact_surfaces(spec, physics, *mesh_, *part_);
    return true;
  }
  Model::MeshCounts held() const override {
    return {mesh_->num_nodes(), mesh_->num_cells(), static_cast<long long>(mesh_->cells.size())};
  }
  void describe(const ProblemSpec& spec, nlohmann::json& j) const override {
    j["bodies"] = part_->num_bodies;
    j["mesh"] = spec.mesh_file.empty() ? BoxSplit::box_description(spec)
                                       : nlohmann::json{{"file", spec.mesh_file},
                                                        {"element", to_string(mesh_->type)},
                                                        {"nodes", mesh_->num_nodes()},
                                                        {"cells", mesh_->num_cells()}};
    j["partitioner"] = "metis";
    j["partition_objective"] = to_string(part_->objective);
    j["partition_seed"] = spec.partition_seed;
    j["partition_repaired_cells"] = part_->repaired_cells;
    j["partition_contiguous_splits"] = part_->contiguous_splits;
    // The split's wall seconds (rank 0's when it split for all; the report keeps the timings
    // of the describing model and adds its own).
    j["timings"] = {{"partition", part_->seconds}};
    if (spec.cluster_size > 1) j["cluster_split"] = to_string(part_->cluster_split);
    if (spec.partition_objective == PartitionObjective::automatic)
      j["stretched_cells"] = part_->stretched_share;
    j["partition_jump_ratio"] = spec.partition_jump_ratio;
    j["partition_jump_regions"] = part_->jump_regions;
    j["partition_jump_splits_declined"] = part_->jump_splits_declined;
    j["partition_shape"] = to_string(spec.partition_shape);
    j["partition_compact_splits"] = part_->compact_splits;
    j["partition_compact_declined"] = part_->compact_declined;
  }

 private:
  std::unique_ptr<Mesh> mesh_;
  std::unique_ptr<MeshPartition> part_;
};

// A whole mesh split by METIS on rank 0 alone, which then sends every rank the subdomains of its
// clusters (FetiLayout::cluster_range) and frees the whole mesh: the other ranks never hold it,
// and METIS runs once instead of on every rank. Used for mesh.file and a generated box split by
// METIS when the model is made over a communicator of several ranks. The subdomain meshes are
// extract_subdomain's on rank 0, sent as their bytes, so the results are those of MetisSplit on
// every rank, bit for bit. Also sent: 3 counts per subdomain, the group names, the report's
// description and, for contact between bodies, the contact surfaces (only their facets and
// nodes). Cost on rank 0: the whole mesh and its partition (as MetisSplit on every rank before)
// plus the packed subdomains of one rank at a time.
class ScatteredSplit final : public HeldSubdomains {
 public:
  ScatteredSplit(const ProblemSpec& spec, const Comm& comm, const Physics& physics)
      : HeldSubdomains(comm) {
    const int P = comm.size(), rank = comm.rank();
    std::unique_ptr<MetisSplit> whole;
    Packer head;  // what every rank gets
    std::vector<Packer> to(P);
    agreed(comm, [&] {
      if (rank != 0) return;
      Physics ph = physics;
      if (spec.mesh_file.empty()) {  // checked before the box is generated whole
        ph.dim = spec.box.dim;
        ph.validate();
      }
      whole = std::make_unique<MetisSplit>(spec);
      ph.dim = whole->dim();
      ph.validate();
      whole->split(spec, ph);
      const int ns = whole->num_subdomains(), nk = whole->num_clusters();
      head.pod(whole->dim()), head.pod(ns), head.pod(whole->num_nodes());
      head.pod(whole->subdomain_nodes());
      std::vector<int> first(nk + 1);
      for (int c = 0; c <= nk; ++c) first[c] = whole->cluster_first(c);
      head.vec(first);
      std::set<std::string> names[3];
      whole->groups(names[0], names[1], names[2]);
      for (const auto& set : names) {
        head.pod(static_cast<long long>(set.size()));
        for (const auto& n : set) head.str(n);
      }
      nlohmann::json j;
      whole->describe(spec, j);
      head.str(j.dump());
      const bool pairs = std::any_of(spec.contact.begin(), spec.contact.end(),
                                     [](const auto& c) { return !c.master.empty(); });
      head.pod(static_cast<char>(pairs));
      if (pairs) {
        ContactSurfaces cs;
        whole->contact_surfaces(spec, ph, cs);
        pack(head, cs);
      }
    });
    broadcast(head.bytes());
    Unpacker h(head.bytes().data(), head.bytes().size());
    h.pod(dim_), h.pod(subdomains_), h.pod(nodes_), h.pod(subdomain_nodes_);
    h.vec(cluster_first_);
    for (auto* names : {&node_names_, &facet_names_, &cell_names_}) {
      long long n = 0;
      h.pod(n);
      names->resize(n);
      for (auto& name : *names) h.str(name);
    }
    std::string description;
    h.str(description);
    description_ = nlohmann::json::parse(description);
    char pairs = 0;
    h.pod(pairs);
    if (pairs) unpack(h, surfaces_), has_surfaces_ = true;

    // The subdomains, rank by rank; rank 0 keeps its own. A failure on rank 0 (out of memory)
    // is sent to the ranks still waiting as a message of length -1, then agreed on by all.
    FetiLayout L;
    L.num_clusters = num_clusters();
    std::vector<long long> counts(3 * static_cast<size_t>(subdomains_), 0);
    std::string error;
    bool oom = false;  // bad input's exit code, as every out-of-memory path
    for (int r = 0; r < P; ++r) {
      const auto [c0, c1] = L.cluster_range(r, P);
      const int s0 = cluster_first_[c0], s1 = cluster_first_[c1];
      if (rank == 0) {
        Packer out;
        try {
          if (!error.empty()) throw std::runtime_error(error);
          if (r > 0) inject_failure("scatter", 0);
          for (int s = s0; s < s1; ++s) {
            SubdomainMesh m = whole->mesh(s);
            counts[3 * s] = m.num_nodes(), counts[3 * s + 1] = m.num_cells();
            counts[3 * s + 2] = static_cast<long long>(m.cells.size());
            if (r == 0)
              meshes_[s] = std::move(m);
            else
              pack(out, m);
          }
        } catch (const std::bad_alloc&) {
          if (error.empty()) error = "out of memory while splitting the mesh", oom = true;
        } catch (const std::exception& e) {
          if (error.empty()) error = e.what();
        }
        if (r > 0) send(out.bytes(), r, !error.empty());
      } else if (rank == r) {
        std::vector<char> in;
        if (receive(0, in)) {
          Unpacker u(in.data(), in.size());
          for (int s = s0; s < s1; ++s) unpack(u, meshes_[s]);
        } else {
          error = "rank 0 failed to send the subdomain meshes";
        }
      }
    }
    comm.agree(error, oom);
    whole.reset();
    MPI_Bcast(counts.data(), static_cast<int>(counts.size()), MPI_LONG_LONG, 0, comm.raw());
    counts_.resize(subdomains_);
    for (int s = 0; s < subdomains_; ++s)
      counts_[s] = {counts[3 * s], counts[3 * s + 1], counts[3 * s + 2]};
  }
  int dim() const override { return dim_; }
  int num_subdomains() const override { return subdomains_; }
  int num_clusters() const override { return static_cast<int>(cluster_first_.size()) - 1; }
  int cluster_first(int c) const override { return cluster_first_[c]; }
  long long num_nodes() const override { return nodes_; }
  long long subdomain_nodes() const override { return subdomain_nodes_; }
  void describe(const ProblemSpec&, nlohmann::json& j) const override {
    for (const auto& [k, v] : description_.items()) j[k] = v;
  }
  bool contact_surfaces(const ProblemSpec&, const Physics&, ContactSurfaces& out) const override {
    if (!has_surfaces_) return false;
    out = surfaces_;
    return true;
  }

 private:
  static constexpr long long kChunk = 1LL << 30;  // bytes per MPI message
  void broadcast(std::vector<char>& b) const {
    long long n = static_cast<long long>(b.size());
    MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm_.raw());
    b.resize(static_cast<size_t>(n));
    for (long long at = 0; at < n; at += kChunk)
      MPI_Bcast(b.data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, 0,
                comm_.raw());
  }
  // Sends b to rank r, or only the length -1 when failed.
  void send(const std::vector<char>& b, int r, bool failed) const {
    long long n = failed ? -1 : static_cast<long long>(b.size());
    MPI_Send(&n, 1, MPI_LONG_LONG, r, 0, comm_.raw());
    if (failed) return;
    for (long long at = 0; at < n; at += kChunk)
      MPI_Send(b.data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, r, 0,
               comm_.raw());
  }
  // Receives into b what send sent; false when the sender failed.
  bool receive(int from, std::vector<char>& b) const {
    long long n = 0;
    MPI_Recv(&n, 1, MPI_LONG_LONG, from, 0, comm_.raw(), MPI_STATUS_IGNORE);
    if (n < 0) return false;
    b.resize(static_cast<size_t>(n));
    for (long long at = 0; at < n; at += kChunk)
      MPI_Recv(b.data() + at, static_cast<int>(std::min(kChunk, n - at)), MPI_BYTE, from, 0,
               comm_.raw(), MPI_STATUS_IGNORE);
    return true;
  }

  std::string where() const override { return "rank 0 split the mesh"; }

  int dim_ = 3, subdomains_ = 0;
  long long nodes_ = 0, subdomain_nodes_ = 0;
  std::vector<int> cluster_first_;
  nlohmann::json description_;
  ContactSurfaces surfaces_;
  bool has_surfaces_ = false;
};

// Laplace or elasticity with conditions on named groups, on a mesh source.
class GroupModel final : public Model {
 public:
  bool has_contact() const override { return !spec_.contact.empty(); }
  std::vector<ContactCondition> contact_conditions() const override {
    std::vector<ContactCondition> out;
    for (const auto& c : spec_.contact) out.push_back({c.group, c.master});
    return out;
  }
  GroupModel(const ProblemSpec& spec, const Comm* comm) : spec_(spec), source_(spec.source) {
    physics_ = spec.physics;
    glue_ = spec.glue;
    const bool box_split = spec.mesh_file.empty() && spec.subdomains.size() > 1;
    if (!spec.mesh_parts.empty()) {
      mesh_source_ = make_partitioned_source(spec, comm ? *comm : Comm(MPI_COMM_WORLD));
      physics_.dim = mesh_source_->dim();
      physics_.validate();
    } else if (box_split) {
      physics_.dim = spec.box.dim;
      physics_.validate();
      mesh_source_ = std::make_unique<BoxSplit>(spec);
    } else if (comm && comm->size() > 1) {
      mesh_source_ = std::make_unique<ScatteredSplit>(spec, *comm, physics_);
      physics_.dim = mesh_source_->dim();
      physics_.validate();
    } else {
      if (spec.mesh_file.empty()) {  // checked before the box is generated whole
        physics_.dim = spec.box.dim;
        physics_.validate();
      }
      auto metis = std::make_unique<MetisSplit>(spec);
      if (!spec.mesh_file.empty()) {  // the dimension is the mesh's
        physics_.dim = metis->dim();
        physics_.validate();
      }
      metis->split(spec, physics_);
      mesh_source_ = std::move(metis);
    }
    check_groups();
    const auto pair = std::find_if(spec.contact.begin(), spec.contact.end(),
                                   [](const auto& c) { return !c.master.empty(); });
    if (pair != spec.contact.end()) {
      ContactSurfaces surfaces;
      if (!mesh_source_->contact_surfaces(spec, physics_, surfaces))
        throw std::invalid_argument(
            "problem file: contact #" + std::to_string(pair - spec.contact.begin() + 1) +
            ": contact between bodies needs a mesh of several bodies (a Gmsh file; a generated "
            "box is one body)");
      pairs_ = ContactPairs(spec, physics_, surfaces);
    }
  }

  int num_subdomains() const override { return mesh_source_->num_subdomains(); }
  int num_clusters() const override { return mesh_source_->num_clusters(); }
  int cluster_first(int c) const override { return mesh_source_->cluster_first(c); }
  long long num_nodes() const override { return mesh_source_->num_nodes(); }
  long long primal_dimension() const override {
    return mesh_source_->subdomain_nodes() * physics_.dofs_per_node();
  }
  SubdomainMesh mesh(int s) const override { return mesh_source_->mesh(s); }
  MeshCounts held() const override { return mesh_source_->held(); }
  MeshCounts mesh_counts(int s) const override {
    MeshCounts counts;
    return mesh_source_->mesh_counts(s, counts) ? counts : Model::mesh_counts(s);
  }
  SourceFunction source() const override {
    if (physics_.kind != PhysicsKind::laplace || spec_.source == "0") return {};
    const Expression e = source_;
    return [e](const std::array<double, 3>& p) mutable { return e(p); };
  }
  void apply_conditions(const SubdomainMesh& m, SubdomainInput& in) const override {
    const int dpn = physics_.dofs_per_node();
    auto point = [&](int k) {
      return std::array<double, 3>{m.coords[3 * k], m.coords[3 * k + 1], m.coords[3 * k + 2]};
    };
    // Loads.
    for (const auto& l : spec_.loads) {
      if (l.kind == ProblemSpec::Load::traction) {
        auto it = m.facet_groups.find(l.group);
        if (it != m.facet_groups.end()) add_traction(m, it->second, physics_, l.value, in.system.f);
        continue;
      }
      auto it = m.cell_groups.find(l.group);
      if (it == m.cell_groups.end()) continue;
      const int nc = cell_nodes(m.type);
      double x[24];
      for (int e : it->second) {
        const int* cn = m.cells.data() + static_cast<size_t>(e) * nc;
        for (int a = 0; a < nc; ++a)
          for (int d = 0; d < 3; ++d) x[3 * a + d] = m.coords[3 * static_cast<size_t>(cn[a]) + d];
        const double share = cell_measure(m.type, x) / nc;
        for (int a = 0; a < nc; ++a)
          for (int d = 0; d < dpn; ++d)
            in.system.f[cn[a] * dpn + d] +=
                (l.kind == ProblemSpec::Load::source ? l.value[0] : l.value[d]) * share;
      }
    }
    // Dirichlet dofs (the first condition on a dof wins).
    std::set<std::pair<int, int>> fixed;
    for (const auto& d : spec_.dirichlet) {
      auto it = m.node_groups.find(d.group);
      if (it == m.node_groups.end()) continue;
      std::vector<int> comps = d.components;
      if (comps.empty())
        for (int c = 0; c < dpn; ++c) comps.push_back(c);
      for (int k : it->second)
        for (int c : comps)
          if (c < dpn && fixed.insert({k, c}).second) in.dirichlet.push_back({k, c, d.value[c]});
    }
    // Contact rows on the nodes of the contact groups: one per node and condition (a node may
    // touch several obstacles); dropped where a Dirichlet condition fixes every component the
    // direction involves. Two conditions on a node with opposite directions whose gaps leave
    // no room (n.u <= g1 and -n.u <= g2 with g1 + g2 < 0) are infeasible: refused.
    std::vector<std::vector<const ContactRow*>> at_node(m.num_nodes());
    const size_t first_row = in.contact.size();
    for (size_t ci = 0; ci < spec_.contact.size(); ++ci) {
      const auto& c = spec_.contact[ci];
      auto it = m.node_groups.find(c.group);
      if (it == m.node_groups.end() || !c.master.empty()) continue;  // pairs: below
      const Expression gap(c.gap);
      // Each node's share of the group's facets on this subdomain (summed over the copies
      // later, in the FETI stage): the contact area of its row (pressure, Tresca's bound).
      std::vector<double> area(m.num_nodes(), 0.0);
      if (auto fg = m.facet_groups.find(c.group); fg != m.facet_groups.end())
        add_facet_shares(m, fg->second, area);
      const bool friction = c.slip_bound >= 0 || c.friction_coefficient >= 0;
      const auto tangent = friction_tangent(c.direction, reference_axis(c.direction));
      std::set<int> done;
      for (int k : it->second) {
        if (!done.insert(k).second) continue;
        bool all_fixed = true;
        for (int d = 0; d < dpn; ++d)
          if (c.direction[d] != 0 && !fixed.count({k, d})) all_fixed = false;
        if (all_fixed) continue;
        ContactRow r;
        r.node = k;
        r.side = 1;
        r.node_a = m.global_node[k];
        r.copies = m.num_copies(k);
        r.norm_sq = 1.0 / r.copies;
        r.owner_subdomain = *std::min_element(m.copies(k), m.copies(k) + m.num_copies(k));
        r.direction = c.direction;
        if (dpn == 1) r.direction = {c.direction[0] < 0 ? -1.0 : 1.0, 0, 0};
        r.point = point(k);
        r.gap = gap(r.point);
        if (!std::isfinite(r.gap))
          throw std::invalid_argument("problem file: contact #" + std::to_string(ci + 1) +
                                      ".gap is not finite at (" + point_text(r.point) + ")");
        r.condition = static_cast<int>(ci);
        r.area = area[k];
        if (friction) {
          // Where a Dirichlet condition fixes a component of the tangent plane: in 2D no
          // tangential row (it would repeat the Dirichlet row, t = (-n_y, n_x) fixed); in 3D the
          // one direction left free, or none (friction_rows_at).
          bool t_fixed = dpn == 2;
          FrictionRows f{dpn - 1, tangent};
          if (dpn == 2) {
            for (int d = 0; d < dpn; ++d)
              if (c.direction[1 - d] != 0 && !fixed.count({k, d})) t_fixed = false;
          } else {
            f = friction_rows_at(
                c.direction, tangent,
                {fixed.count({k, 0}) > 0, fixed.count({k, 1}) > 0, fixed.count({k, 2}) > 0});
            t_fixed = f.rows == 0;
          }
          if (!t_fixed) {
            r.slip_bound = c.slip_bound;
            r.friction_coefficient = c.friction_coefficient;
            r.tangent = f.tangent;
            r.tangent_rows = f.rows;
          }
        }
        in.contact.push_back(r);
      }
    }
    for (size_t i = first_row; i < in.contact.size(); ++i)
      at_node[in.contact[i].node].push_back(&in.contact[i]);
    for (const auto& rows : at_node)
      for (size_t a = 0; a < rows.size(); ++a)
        for (size_t b = a + 1; b < rows.size(); ++b) {
          bool opposite = true;
          for (int d = 0; d < 3; ++d)
            opposite &= std::abs(rows[a]->direction[d] + rows[b]->direction[d]) < 1e-12;
          if (opposite && rows[a]->gap + rows[b]->gap < 0)
            throw std::invalid_argument(
                "problem file: contact #" + std::to_string(rows[a]->condition + 1) +
                " and contact #" + std::to_string(rows[b]->condition + 1) +
                " cannot both hold at (" + point_text(rows[a]->point) +
                "): opposite directions whose gaps add up to " +
                std::to_string(rows[a]->gap + rows[b]->gap) + " < 0 (no feasible position)");
        }
    // Contact between bodies: the parts of the mortar rows on this subdomain's nodes (after the
    // check above, which is for obstacles and holds pointers into in.contact).
    pairs_.add_rows(m, in);
  }
  nlohmann::json describe() const override {
    nlohmann::json j;
    j["problem"] = spec_.path;
    mesh_source_->describe(spec_, j);
    j["element"] = j["mesh"]["element"];
    nlohmann::json ph = {{"type", to_string(physics_.kind)}, {"dim", physics_.dim}};
    if (physics_.kind == PhysicsKind::elasticity) {
      ph["young"] = physics_.material.young;
      ph["poisson"] = physics_.material.poisson;
      ph["density"] = physics_.density;
      ph["gravity"] =
          std::vector<double>(physics_.gravity.begin(), physics_.gravity.begin() + physics_.dim);
    } else {
      ph["source"] = spec_.source;
    }
    if (!physics_.coefficient.empty()) ph["coefficient"] = physics_.coefficient;
    j["physics"] = ph;
    // The conditions as the solver reads them (groups, values, directions, gaps, friction).
    const int dpn = physics_.dofs_per_node();
    nlohmann::json conditions = {{"dirichlet", nlohmann::json::array()},
                                 {"load", nlohmann::json::array()},
                                 {"contact", nlohmann::json::array()}};
    for (const auto& d : spec_.dirichlet) {
      std::vector<int> comps = d.components;
      if (comps.empty())
        for (int c = 0; c < dpn; ++c) comps.push_back(c);
      std::vector<double> value;
      for (int c : comps) value.push_back(d.value[c]);
      conditions["dirichlet"].push_back(
          {{"group", d.group}, {"components", comps}, {"value", value}});
    }
    for (const auto& l : spec_.loads) {
      const char* kind = l.kind == ProblemSpec::Load::traction ? "traction"
                         : l.kind == ProblemSpec::Load::source ? "source"
                                                               : "force";
      conditions["load"].push_back(
          {{"group", l.group},
           {kind, l.kind == ProblemSpec::Load::source
                      ? nlohmann::json(l.value[0])
                      : nlohmann::json(std::vector<double>(l.value.begin(),
                                                           l.value.begin() + physics_.dim))}});
    }
    for (size_t ci = 0; ci < spec_.contact.size(); ++ci) {
      const auto& c = spec_.contact[ci];
      if (!c.master.empty()) {
        nlohmann::json cj = {{"group", c.group}, {"master", c.master}, {"rows", "mortar"}};
        const nlohmann::json pair = pairs_.describe(static_cast<int>(ci));
        for (const auto& [k, v] : pair.items()) cj[k] = v;
        if (physics_.kind == PhysicsKind::laplace)
          cj["direction"] = c.direction[0], cj["gap"] = c.gap;
        if (c.slip_bound >= 0) cj["friction"] = {{"law", "tresca"}, {"bound", c.slip_bound}};
        if (c.friction_coefficient >= 0)
          cj["friction"] = {{"law", "coulomb"}, {"coefficient", c.friction_coefficient}};
        conditions["contact"].push_back(cj);
        continue;
      }
      nlohmann::json cj = {
          {"group", c.group},
          {"direction", std::vector<double>(c.direction.begin(), c.direction.begin() + dpn)},
          {"gap", c.gap}};
      if (c.slip_bound >= 0) cj["friction"] = {{"law", "tresca"}, {"bound", c.slip_bound}};
      if (c.friction_coefficient >= 0)
        cj["friction"] = {{"law", "coulomb"}, {"coefficient", c.friction_coefficient}};
      conditions["contact"].push_back(cj);
    }
    j["conditions"] = conditions;
    j["subdomains"] = num_subdomains();
    j["clusters"] = num_clusters();
    j["cluster_size"] = spec_.cluster_size;
    j["glue"] = spec_.cluster_size > 1 ? to_string(glue_) : "none";
    return j;
  }

 private:
  void check_groups() const {
    std::set<std::string> nodes, facets, cells;
    mesh_source_->groups(nodes, facets, cells);
    const std::string where = !spec_.mesh_parts.empty() ? "the parts of " + spec_.mesh_parts
                              : spec_.mesh_file.empty() ? "the generated box"
                                                        : spec_.mesh_file;
    auto require = [&](const std::string& g, const std::set<std::string>& in,
                       const std::string& what) {
      if (!in.count(g))
        throw std::invalid_argument("problem file: " + what + ": group '" + g +
                                    "' does not exist in " + where +
                                    " (its groups: " + list_groups(in) + ")");
    };
    int i = 0;
    for (const auto& d : spec_.dirichlet)
      require(d.group, nodes, "dirichlet #" + std::to_string(++i));
    i = 0;
    for (const auto& l : spec_.loads) {
      ++i;
      if (l.kind == ProblemSpec::Load::traction)
        require(l.group, facets,
                "load #" + std::to_string(i) + " (a traction needs a boundary group)");
      else
        require(l.group, cells,
                "load #" + std::to_string(i) + " (a source or force needs a volume group)");
      if (l.kind == ProblemSpec::Load::source && physics_.kind != PhysicsKind::laplace)
        throw std::invalid_argument("problem file: load #" + std::to_string(i) +
                                    ": 'source' is for Laplace; use 'force' for elasticity");
      if (l.kind == ProblemSpec::Load::force && physics_.kind != PhysicsKind::elasticity)
        throw std::invalid_argument("problem file: load #" + std::to_string(i) +
                                    ": 'force' is for elasticity; use 'source' for Laplace");
    }
    i = 0;
    for (const auto& c : spec_.contact) {
      const std::string what = "contact #" + std::to_string(++i);
      require(c.group, nodes, what);
      if (!c.master.empty()) {
        require(c.group, facets, what + " (the slave surface of contact between bodies)");
        require(c.master, facets, what + ".master (a master surface)");
      }
      if (c.slip_bound < 0 && c.friction_coefficient < 0) continue;
      if (physics_.kind != PhysicsKind::elasticity)
        throw std::invalid_argument("problem file: " + what +
                                    ".friction: friction needs elasticity (a tangential "
                                    "displacement), not " +
                                    to_string(physics_.kind));
      require(c.group, facets, what + ".friction (the friction acts on the contact area)");
    }
    check_components();
  }

  // Components the problem does not have are refused, not ignored: a third component of a
  // direction or a Dirichlet component 2 in 2D, a direction other than +1 or -1 for Laplace.
  void check_components() const {
    const int dpn = physics_.dofs_per_node();
    int i = 0;
    for (const auto& d : spec_.dirichlet) {
      ++i;
      for (int c : d.components)
        if (c >= dpn)
          throw std::invalid_argument("problem file: dirichlet #" + std::to_string(i) +
                                      ".components: component " + std::to_string(c) +
                                      " does not exist in this " + std::to_string(physics_.dim) +
                                      "D " + to_string(physics_.kind) + " problem");
    }
    i = 0;
    for (const auto& c : spec_.contact) {
      ++i;
      if (!c.master.empty() && dpn > 1) continue;  // the normal comes from the meshes
      const std::string where = "problem file: contact #" + std::to_string(i) + ".direction: ";
      if (dpn == 1) {
        if (c.direction[1] != 0 || c.direction[2] != 0)
          throw std::invalid_argument(where +
                                      "a Laplace problem takes one component (1: u <= gap, "
                                      "-1: u >= -gap)");
      } else {
        for (int d = dpn; d < 3; ++d)
          if (c.direction[d] != 0)
            throw std::invalid_argument(where + "has a component " + std::to_string(d) +
                                        " that this " + std::to_string(physics_.dim) +
                                        "D problem does not have");
      }
    }
  }

  ProblemSpec spec_;
  Expression source_;
  std::unique_ptr<MeshSource> mesh_source_;
  ContactPairs pairs_;
};

}  // namespace

ProblemSpec cube_obstacle_spec(const std::vector<int>& elements, const std::vector<int>& subdomains,
                               int cluster_size, double amplitude, CellType cell) {
  auto three = [](const std::vector<int>& v, const char* what) {
    if (v.size() == 1) return std::vector<int>{v[0], v[0], v[0]};
    if (v.size() != 3)
      throw std::invalid_argument(std::string(what) + " needs 1 or 3 numbers for cube-obstacle");
    return v;
  };
  if (!std::isfinite(amplitude) || amplitude < 0)
    throw std::invalid_argument("--obstacle-amplitude must be finite and non-negative");
  ProblemSpec s;
  s.path = "cube-obstacle";
  s.box.dim = 3;
  s.box.cell = cell;
  s.box.size = {100, 100, 100};
  const auto e = three(elements, "--elements");
  for (int d = 0; d < 3; ++d) s.box.elements[d] = e[d];
  s.physics.kind = PhysicsKind::elasticity;
  s.physics.dim = 3;
  s.physics.material = {2.1e7, 0.3};
  s.physics.density = 7850;
  s.physics.gravity = {0, 0, -9.8066};
  s.dirichlet.push_back({"x0", {0, 0, 0}, {}});
  std::ostringstream gap;
  gap.precision(17);
  gap << amplitude << "*sin(pi*x/50)";
  ProblemSpec::Contact c;
  c.group = "z0";
  c.direction = {0, 0, -1};
  c.gap = gap.str();
  s.contact.push_back(c);
  s.subdomains = three(subdomains, "--subdomains");
  s.cluster_size = cluster_size;
  s.glue = Glue::averages;
  return s;
}

std::unique_ptr<Model> make_model(const ProblemSpec& spec, const Comm* comm) {
  if (!spec.builtin.empty()) {
    DecompositionOptions o = spec.builtin_options;
    if (spec.subdomains.size() != 1)
      throw std::invalid_argument("decomposition.subdomains: one number (per side) for a built-in");
    o.subdomains = spec.subdomains[0];
    o.cluster_size = spec.cluster_size;
    o.glue = spec.glue;
    Decomposition check(o);
    return make_builtin_model(o);
  }
  return std::make_unique<GroupModel>(spec, comm);
}

}  // namespace htfeti
