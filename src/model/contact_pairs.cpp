// Contact between bodies (contact_pairs.hpp).
#include "htfeti/model/contact_pairs.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

#include "htfeti/expression.hpp"
#include "htfeti/model/mortar.hpp"

namespace htfeti {

namespace {

// The facets of a boundary group of the whole mesh with their outward normals (away from the
// one cell each bounds) and the bodies they lie on; or why the group cannot be a surface.
ContactSurfaces::Group surface_of(const Mesh& mesh, const MeshPartition& part,
                                  const std::string& group) {
  ContactSurfaces::Group g;
  auto it = mesh.facet_groups.find(group);
  if (it == mesh.facet_groups.end() || it->second.nodes.empty()) {
    g.error = no_facets_error(group, mesh.dim);
    return g;
  }
  const int fn = it->second.facet_nodes, nc = cell_nodes(mesh.type);
  ContactSurface& s = g.surface;
  s.facet_nodes = fn;
  s.nodes = it->second.nodes;
  std::set<int> body_set;
  for (int f = 0; f < s.num_facets(); ++f) {
    const int* v = s.nodes.data() + static_cast<size_t>(f) * fn;
    int cell = -1, cells = 0;
    for (int c = part.node_cell_offset[v[0]]; c < part.node_cell_offset[v[0] + 1]; ++c) {
      const int e = part.node_cell_list[c];
      if (cell_holds_facet(mesh.cells.data() + static_cast<size_t>(e) * nc, nc, v, fn))
        cell = e, ++cells;
    }
    if (cells != 1) {
      g.error = not_boundary_error(group, v[0] + 1, v[1] + 1);
      return g;
    }
    body_set.insert(part.cell_body[cell]);
    s.normals.push_back(outward_normal(mesh.dim, mesh.coords.data(), v, fn,
                                       mesh.cells.data() + static_cast<size_t>(cell) * nc, nc));
  }
  g.bodies.assign(body_set.begin(), body_set.end());
  return g;
}

}  // namespace

std::string no_facets_error(const std::string& group, int dim) {
  return "group '" + group +
         "' has no boundary facets (a contact surface is a physical group of dimension " +
         std::to_string(dim - 1) + ")";
}

std::string not_boundary_error(const std::string& group, long long tag0, long long tag1) {
  return "group '" + group + "' has a facet that is not on the boundary of a body (nodes " +
         std::to_string(tag0) + ", " + std::to_string(tag1) + ", ...)";
}

bool cell_holds_facet(const int* cell, int nc, const int* facet, int fn) {
  int hits = 0;
  for (int a = 0; a < nc; ++a)
    for (int b = 0; b < fn; ++b) hits += cell[a] == facet[b];
  return hits == fn;
}

std::array<double, 3> outward_normal(int dim, const double* coords, const int* v, int fn,
                                     const int* cell, int nc) {
  auto x = [&](int node, int d) { return coords[3 * static_cast<size_t>(node) + d]; };
  std::array<double, 3> n{0, 0, 0}, fc{0, 0, 0}, cc{0, 0, 0};
  if (dim == 2) {
    n = {x(v[1], 1) - x(v[0], 1), x(v[0], 0) - x(v[1], 0), 0};
  } else {
    const int p = fn == 4 ? 2 : 1, q = fn == 4 ? 3 : 2;  // quad: the diagonals
    const double a[3] = {x(v[p], 0) - x(v[0], 0), x(v[p], 1) - x(v[0], 1), x(v[p], 2) - x(v[0], 2)};
    const int r = fn == 4 ? 1 : 0;
    const double b[3] = {x(v[q], 0) - x(v[r], 0), x(v[q], 1) - x(v[r], 1), x(v[q], 2) - x(v[r], 2)};
    n = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  }
  for (int d = 0; d < 3; ++d) {
    for (int b = 0; b < fn; ++b) fc[d] += x(v[b], d) / fn;
    for (int a = 0; a < nc; ++a) cc[d] += x(cell[a], d) / nc;
  }
  double len = 0, side = 0;
  for (int d = 0; d < 3; ++d) len += n[d] * n[d], side += n[d] * (fc[d] - cc[d]);
  len = std::sqrt(len) * (side < 0 ? -1.0 : 1.0);
  for (double& c : n) c /= len;
  return n;
}

std::vector<unsigned char> fixed_components(
    const ProblemSpec& spec, int dofs_per_node,
    const std::map<std::string, std::vector<int>>& node_groups, int nodes) {
  std::vector<unsigned char> fixed(nodes, 0);
  for (const auto& d : spec.dirichlet) {
    auto it = node_groups.find(d.group);
    if (it == node_groups.end()) continue;
    for (int k : it->second)
      for (int c = 0; c < dofs_per_node; ++c)
        if (d.components.empty() ||
            std::find(d.components.begin(), d.components.end(), c) != d.components.end())
          fixed[k] |= static_cast<unsigned char>(1u << c);
  }
  return fixed;
}

ContactSurfaces contact_surfaces(const ProblemSpec& spec, const Physics& physics, const Mesh& mesh,
                                 const MeshPartition& part) {
  ContactSurfaces cs;
  cs.dim = mesh.dim;
  cs.num_bodies = part.num_bodies;
  for (const auto& c : spec.contact)
    if (!c.master.empty())
      for (const std::string* g : {&c.group, &c.master})
        if (!cs.groups.count(*g)) cs.groups[*g] = surface_of(mesh, part, *g);
  // The surface nodes: the groups' nodes in global order (the rows come out in the same order
  // as over all the mesh's nodes).
  std::vector<long long>& nodes = cs.global;
  for (const auto& [name, g] : cs.groups)
    nodes.insert(nodes.end(), g.surface.nodes.begin(), g.surface.nodes.end());
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  for (auto& [name, g] : cs.groups)
    for (int& v : g.surface.nodes)
      v = static_cast<int>(std::lower_bound(nodes.begin(), nodes.end(), v) - nodes.begin());
  const std::vector<unsigned char> fixed =
      fixed_components(spec, physics.dofs_per_node(), mesh.node_groups, mesh.num_nodes());
  for (const long long k : nodes) {
    for (int d = 0; d < 3; ++d) cs.coords.push_back(mesh.coords[3 * static_cast<size_t>(k) + d]);
    cs.copies.push_back(part.copy_offset[k + 1] - part.copy_offset[k]);
    cs.owner.push_back(part.copy_list[part.copy_offset[k]]);
    cs.fixed.push_back(fixed[k]);
  }
  return cs;
}

std::array<double, 3> reference_axis(const std::array<double, 3>& n) {
  int d = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(n[i]) < std::abs(n[d])) d = i;
  std::array<double, 3> a{0, 0, 0};
  a[d] = 1;
  return a;
}

std::array<double, 3> friction_tangent(const std::array<double, 3>& n,
                                       const std::array<double, 3>& a) {
  const double an = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
  std::array<double, 3> t{a[0] - an * n[0], a[1] - an * n[1], a[2] - an * n[2]};
  const double len = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  for (double& v : t) v /= len;
  return t;
}

FrictionRows friction_rows_at(const std::array<double, 3>& n, const std::array<double, 3>& t1,
                              const std::array<bool, 3>& fixed) {
  FrictionRows f;
  f.tangent = t1;
  int in_plane = -1;
  for (int d = 0; d < 3; ++d)
    if (fixed[d] && std::abs(n[d]) < 1 - 1e-12) {
      if (in_plane >= 0) return {0, t1};  // two fixed axes: no tangential motion left
      in_plane = d;
    }
  if (in_plane < 0) return f;
  // t = n x e_d, normalized: orthogonal to the fixed axis and to n.
  const int a = (in_plane + 1) % 3, b = (in_plane + 2) % 3;
  std::array<double, 3> t{0, 0, 0};
  t[a] = n[b], t[b] = -n[a];
  const double len = std::hypot(t[a], t[b]);
  for (double& v : t) v /= len;
  return {1, t};
}

ContactPairs::ContactPairs(const ProblemSpec& spec, const Physics& physics,
                           const ContactSurfaces& cs) {
  const int dpn = physics.dofs_per_node();
  info_.resize(spec.contact.size());
  auto fixed = [&](int k, int c) { return (cs.fixed[k] >> c & 1) != 0; };
  std::set<std::pair<std::string, std::string>> seen;
  for (size_t ci = 0; ci < spec.contact.size(); ++ci) {
    const auto& c = spec.contact[ci];
    if (c.master.empty()) continue;
    const std::string what = "problem file: contact #" + std::to_string(ci + 1);
    if (!seen.insert({c.group, c.master}).second)
      throw std::invalid_argument(what + ": the pair group = '" + c.group + "', master = '" +
                                  c.master + "' is given twice");
    Info& info = info_[ci];
    const ContactSurfaces::Group& sg = cs.groups.at(c.group);
    if (!sg.error.empty()) throw std::invalid_argument(what + ": " + sg.error);
    const ContactSurfaces::Group& mg = cs.groups.at(c.master);
    if (!mg.error.empty()) throw std::invalid_argument(what + ": " + mg.error);
    const ContactSurface &slave = sg.surface, &master = mg.surface;
    info.slave_bodies = sg.bodies;
    info.master_bodies = mg.bodies;
    for (int b : info.slave_bodies)
      if (std::binary_search(info.master_bodies.begin(), info.master_bodies.end(), b))
        throw std::invalid_argument(
            what + ": group '" + c.group + "' and master '" + c.master +
            "' lie on the same body (body " + std::to_string(b + 1) + " of " +
            std::to_string(cs.num_bodies) +
            "; contact is between bodies that share no node: mesh them apart)");
    info.search_distance = c.search_distance > 0
                               ? c.search_distance
                               : 2.0 * std::max(largest_facet_diameter(cs.coords, slave),
                                                largest_facet_diameter(cs.coords, master));
    info.multipliers = c.multipliers;
    const auto rows =
        mortar_rows(cs.dim, cs.coords, slave, master, info.search_distance, c.multipliers);
    info.slip_bound = c.slip_bound;
    info.friction_coefficient = c.friction_coefficient;
    // Friction in 3D: one reference axis for the condition, from the slave surface's mean normal.
    std::array<double, 3> mean{0, 0, 0};
    for (const auto& n : slave.normals)
      for (int d = 0; d < 3; ++d) mean[d] += n[d];
    const auto axis = reference_axis(mean);
    std::vector<int> snodes(slave.nodes);
    std::sort(snodes.begin(), snodes.end());
    const Expression gap(c.gap);
    for (const MortarRow& mr : rows) {
      Row r;
      r.condition = static_cast<int>(ci);
      r.slave = cs.global_node(mr.slave_node);
      r.weight = mr.weight;
      const std::array<double, 3> p{cs.coords[3 * static_cast<size_t>(mr.slave_node)],
                                    cs.coords[3 * static_cast<size_t>(mr.slave_node) + 1],
                                    cs.coords[3 * static_cast<size_t>(mr.slave_node) + 2]};
      if (physics.kind == PhysicsKind::laplace) {
        r.normal = {c.direction[0] < 0 ? -1.0 : 1.0, 0, 0};
        r.gap = gap(p);
      } else {
        r.normal = mr.normal;
        r.gap = mr.gap;
        if (cs.dim == 3) {
          const std::array<bool, 3> held{fixed(mr.slave_node, 0), fixed(mr.slave_node, 1),
                                         fixed(mr.slave_node, 2)};
          const FrictionRows f = friction_rows_at(r.normal, friction_tangent(r.normal, axis), held);
          r.tangent = f.tangent;
          r.tangent_rows = f.rows;
        }
      }
      // A row on dofs that Dirichlet conditions hold all of repeats their rows: dropped.
      bool all_fixed = true;
      for (const auto& [node, cj] : mr.entries)
        for (int d = 0; d < dpn; ++d)
          if (r.normal[d] != 0 && !fixed(node, d)) all_fixed = false;
      if (all_fixed) continue;
      r.owner = INT_MAX;
      for (const auto& [node, cj] : mr.entries) {
        r.norm_sq += cj * cj / cs.copies[node];
        r.owner = std::min(r.owner, cs.owner[node]);
      }
      const int row = static_cast<int>(rows_.size());
      for (const auto& [node, cj] : mr.entries) {
        by_node_.push_back({cs.global_node(node), row, cj,
                            std::binary_search(snodes.begin(), snodes.end(), node)});
      }
      rows_.push_back(r);
      coords_.insert(coords_.end(), p.begin(), p.end());
      ++info.rows;
    }
    if (info.rows == 0)
      throw std::invalid_argument(
          what + ": no facet of group '" + c.group + "' faces a facet of master '" + c.master +
          "' within the search distance " + std::to_string(info.search_distance) +
          " (set search_distance, or check which side each group is on)");
  }
  std::sort(by_node_.begin(), by_node_.end(), [](const Entry& a, const Entry& b) {
    return a.node != b.node ? a.node < b.node : a.row < b.row;
  });
}

void ContactPairs::add_rows(const SubdomainMesh& m, SubdomainInput& in) const {
  if (rows_.empty()) return;
  for (int k = 0; k < m.num_nodes(); ++k) {
    const long long g = m.global_node[k];
    auto lo = std::lower_bound(by_node_.begin(), by_node_.end(), g,
                               [](const Entry& e, long long v) { return e.node < v; });
    for (; lo != by_node_.end() && lo->node == g; ++lo) {
      const Row& row = rows_[lo->row];
      ContactRow r;
      r.node = k;
      r.side = lo->slave ? 1 : -1;
      r.node_a = row.slave;
      r.coefficient = lo->coefficient;
      r.copies = m.num_copies(k);
      r.norm_sq = row.norm_sq;
      r.weight = row.weight;
      r.owner_subdomain = row.owner;
      r.direction = row.normal;
      r.gap = row.gap;
      for (int d = 0; d < 3; ++d) r.point[d] = coords_[3 * static_cast<size_t>(lo->row) + d];
      r.condition = row.condition;
      r.key = g == row.slave;
      r.area = r.key ? row.weight / r.copies : 0.0;
      const Info& info = info_[row.condition];
      r.slip_bound = row.tangent_rows > 0 ? info.slip_bound : -1;
      r.friction_coefficient = row.tangent_rows > 0 ? info.friction_coefficient : -1;
      r.tangent = row.tangent;
      r.tangent_rows = row.tangent_rows;
      in.contact.push_back(r);
    }
  }
}

nlohmann::json ContactPairs::describe(int c) const {
  auto one_based = [](std::vector<int> b) {
    for (int& v : b) ++v;
    return b;
  };
  if (c < 0 || c >= static_cast<int>(info_.size()) || info_[c].rows == 0) return {};
  const Info& i = info_[c];
  return {{"rows", i.rows},
          {"search_distance", i.search_distance},
          {"multipliers", i.multipliers == MortarBasis::dual ? "dual" : "standard"},
          {"slave_bodies", one_based(i.slave_bodies)},
          {"master_bodies", one_based(i.master_bodies)}};
}

}  // namespace htfeti
