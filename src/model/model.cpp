#include "htfeti/model/model.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "htfeti/fem/element.hpp"
#include "htfeti/fem/grid_offsets.hpp"
#include "htfeti/mesh/box.hpp"

namespace htfeti {

FetiLayout Model::layout() const {
  FetiLayout L;
  L.dim = dim();
  L.dofs_per_node = physics_.dofs_per_node();
  L.num_nodes = num_nodes();
  L.num_subdomains = num_subdomains();
  L.num_clusters = num_clusters();
  L.cluster_first.resize(L.num_clusters + 1);
  for (int c = 0; c <= L.num_clusters; ++c) L.cluster_first[c] = cluster_first(c);
  L.glue = glue_;
  const Physics ph = physics_;
  L.kernel = [ph](const double* xyz, int n) { return physics_kernel(ph, xyz, n); };
  return L;
}

Model::MeshCounts Model::mesh_counts(int s) const {
  const SubdomainMesh m = mesh(s);
  return {m.num_nodes(), m.num_cells(), static_cast<long long>(m.cells.size())};
}

Model::MeshCounts box_mesh_counts(const BoxGrid& grid) {
  const long long cells = grid.cells_per_subdomain();
  return {grid.nodes_per_subdomain(), cells, cells * cell_nodes(grid.options().cell)};
}

SubdomainInput Model::input(int s) const {
  SubdomainMesh m = mesh(s);
  SubdomainInput in;
  AssembledSubdomain a = assemble_subdomain(m, physics_, source());
  in.system.id = s;
  in.system.dofs_per_node = physics_.dofs_per_node();
  in.system.K.swap(a.K);  // (Eigen's SparseMatrix copies on move)
  in.system.f = std::move(a.f);
  in.system.R = std::move(a.R);
  in.system.fixed_dofs = std::move(a.fixed_dofs);
  in.system.repeats = m.uniform_period > 0;
  in.system.coefficient_min = a.coefficient_min;
  in.system.coefficient_max = a.coefficient_max;
  const Physics ph = physics_;
  const Model* self = this;
  in.system.assemble = [self, ph, s]() { return assemble_stiffness(self->mesh(s), ph); };
  in.system.quadratic_form = [self, ph, s](const Eigen::VectorXd& u) {
    return stiffness_form(self->mesh(s), ph, u);
  };
  apply_conditions(m, in);
  in.sharing.global_node = std::move(m.global_node);
  in.sharing.coords = std::move(m.coords);
  in.sharing.copy_offset = std::move(m.copy_offset);
  in.sharing.copy_list = std::move(m.copy_list);
  in.sharing.on_boundary = std::move(m.on_boundary);
  if (m.uniform_period > 0) {  // a generated grid: kernels on whole grid spacings
    std::array<double, 3> h{m.uniform_spacing[0], m.uniform_spacing[1], m.uniform_spacing[2]};
    in.sharing.kernel_frame = [h](double* xyz, int n) {
      const double origin[3] = {xyz[0], xyz[1], xyz[2]};
      grid_offsets(h.data(), xyz, xyz, n, origin);
    };
  }
  return in;
}

namespace {

// The built-in problems: Laplace on one or two generated unit squares.
class BuiltinModel final : public Model {
 public:
  explicit BuiltinModel(const DecompositionOptions& o) : dec_(o), grid_(dec_.grid()) {
    physics_.kind = PhysicsKind::laplace;
    physics_.dim = 2;
    glue_ = o.glue;
  }
  bool has_contact() const override { return dec_.options().problem != ProblemKind::poisson2d; }
  std::vector<ContactCondition> contact_conditions() const override {
    if (!has_contact()) return {};
    return {{"membrane1_right", "membrane2_left"}};  // u_a - u_b <= 0 on x = 1
  }
  int num_subdomains() const override { return dec_.num_subdomains(); }
  int num_clusters() const override { return dec_.num_clusters(); }
  int cluster_first(int c) const override { return c * dec_.m() * dec_.m(); }
  long long num_nodes() const override { return grid_.num_nodes(); }
  long long primal_dimension() const override { return dec_.primal_dimension(); }
  SubdomainMesh mesh(int s) const override { return grid_.mesh(s); }
  MeshCounts mesh_counts(int) const override { return box_mesh_counts(grid_); }
  SourceFunction source() const override {
    const Problem p = dec_.problem();
    return [p](const std::array<double, 3>& x) { return p.load(x[0], x[1]); };
  }
  void apply_conditions(const SubdomainMesh& m, SubdomainInput& in) const override {
    const Problem problem = dec_.problem();
    const int n = dec_.n();
    const long long per_box = grid_.nodes_per_box();
    for (int k = 0; k < m.num_nodes(); ++k) {
      const long long g = m.global_node[k];
      const int q = static_cast<int>(g / per_box);
      const int gx = static_cast<int>(g % per_box % (n + 1)),
                gy = static_cast<int>(g % per_box / (n + 1));
      if (problem.dirichlet(q, gx, gy, n)) in.dirichlet.push_back({k, 0, 0.0});
      if (!problem.has_contact()) continue;
      // Contact on x = 1: node a = (square 0, x = n), node b = (square 1, x = 0), u_a - u_b <= 0.
      const bool is_a = q == 0 && gx == n, is_b = q == 1 && gx == 0;
      if (!is_a && !is_b) continue;
      const long long ga[3] = {n, gy, 0}, gb[3] = {0, gy, 0};
      int ca[8], cb[8];
      const int ka = grid_.node_copies(0, ga, ca), kb = grid_.node_copies(1, gb, cb);
      ContactRow c;
      c.node = k;
      c.side = is_a ? 1 : -1;
      c.key = is_a;
      c.node_a = grid_.global_node(0, {ga[0], ga[1], ga[2]});
      c.coefficient = is_a ? 1.0 : -1.0;
      c.copies = is_a ? ka : kb;
      c.norm_sq = 1.0 / ka + 1.0 / kb;
      c.owner_subdomain = std::min(*std::min_element(ca, ca + ka), *std::min_element(cb, cb + kb));
      c.direction = {1, 0, 0};
      c.gap = 0;
      c.point = {1.0, static_cast<double>(gy) / n, 0};
      in.contact.push_back(c);
    }
  }
  nlohmann::json describe() const override {
    const auto& o = dec_.options();
    return {{"problem", to_string(o.problem)},
            {"element", to_string(o.element)},
            {"elements", o.elements},
            {"subdomains", dec_.num_subdomains()},
            {"subdomains_per_side", o.subdomains},
            {"clusters", dec_.num_clusters()},
            {"cluster_size", o.cluster_size},
            {"glue", o.cluster_size > 1 ? to_string(o.glue) : "none"},
            {"H_over_h", dec_.H()},
            {"physics", {{"type", "laplace"}, {"dim", 2}}}};
  }

 private:
  Decomposition dec_;
  BoxGrid grid_;
};

}  // namespace

std::unique_ptr<Model> make_builtin_model(const DecompositionOptions& options) {
  return std::make_unique<BuiltinModel>(options);
}

}  // namespace htfeti
