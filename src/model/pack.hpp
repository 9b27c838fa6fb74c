// Byte packing of what one rank hands another in the model's setup (private to model/): the
// subdomain meshes and contact surfaces that rank 0 sends after splitting a whole mesh
// (group_model.cpp, ScatteredSplit). Values are copied as their bytes, so a mesh arrives with
// the same bits it left with.
#pragma once

#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "htfeti/mesh/subdomain_mesh.hpp"
#include "htfeti/model/contact_pairs.hpp"

namespace htfeti {

class Packer {
 public:
  template <class T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const char*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof v);
  }
  template <class T>
  void vec(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    pod(static_cast<long long>(v.size()));
    const auto* p = reinterpret_cast<const char*>(v.data());
    bytes_.insert(bytes_.end(), p, p + v.size() * sizeof(T));
  }
  void str(const std::string& s) { vec(std::vector<char>(s.begin(), s.end())); }
  std::vector<char>& bytes() { return bytes_; }

 private:
  std::vector<char> bytes_;
};

class Unpacker {
 public:
  Unpacker(const char* data, size_t size) : p_(data), end_(data + size) {}
  template <class T>
  void pod(T& v) {
    take(&v, sizeof v);
  }
  template <class T>
  void vec(std::vector<T>& v) {
    long long n = 0;
    pod(n);
    v.resize(static_cast<size_t>(n));
    take(v.data(), v.size() * sizeof(T));
  }
  void str(std::string& s) {
    std::vector<char> c;
    vec(c);
    s.assign(c.begin(), c.end());
  }
  bool done() const { return p_ == end_; }

 private:
  void take(void* out, size_t n) {
    if (static_cast<size_t>(end_ - p_) < n) throw std::logic_error("unpacking past the message");
    if (n) std::memcpy(out, p_, n);
    p_ += n;
  }
  const char* p_;
  const char* end_;
};

inline void pack(Packer& o, const SubdomainMesh& m) {
  o.pod(m.id), o.pod(m.cluster), o.pod(m.dim), o.pod(m.type), o.pod(m.uniform_period);
  o.pod(m.uniform_spacing);
  o.vec(m.coords), o.vec(m.global_node), o.vec(m.cells), o.vec(m.copy_offset), o.vec(m.copy_list);
  o.vec(m.on_boundary);
  o.pod(static_cast<long long>(m.node_groups.size()));
  for (const auto& [name, v] : m.node_groups) o.str(name), o.vec(v);
  o.pod(static_cast<long long>(m.facet_groups.size()));
  for (const auto& [name, f] : m.facet_groups) o.str(name), o.pod(f.facet_nodes), o.vec(f.nodes);
  o.pod(static_cast<long long>(m.cell_groups.size()));
  for (const auto& [name, v] : m.cell_groups) o.str(name), o.vec(v);
}

inline void unpack(Unpacker& in, SubdomainMesh& m) {
  in.pod(m.id), in.pod(m.cluster), in.pod(m.dim), in.pod(m.type), in.pod(m.uniform_period);
  in.pod(m.uniform_spacing);
  in.vec(m.coords), in.vec(m.global_node), in.vec(m.cells), in.vec(m.copy_offset);
  in.vec(m.copy_list), in.vec(m.on_boundary);
  long long n = 0;
  std::string name;
  in.pod(n);
  for (long long i = 0; i < n; ++i) in.str(name), in.vec(m.node_groups[name]);
  in.pod(n);
  for (long long i = 0; i < n; ++i) {
    in.str(name);
    auto& f = m.facet_groups[name];
    in.pod(f.facet_nodes), in.vec(f.nodes);
  }
  in.pod(n);
  for (long long i = 0; i < n; ++i) in.str(name), in.vec(m.cell_groups[name]);
}

inline void pack(Packer& o, const ContactSurfaces& s) {
  o.pod(s.dim), o.pod(s.num_bodies);
  o.vec(s.coords), o.vec(s.global), o.vec(s.copies), o.vec(s.owner), o.vec(s.fixed);
  o.pod(static_cast<long long>(s.groups.size()));
  for (const auto& [name, g] : s.groups) {
    o.str(name), o.pod(g.surface.facet_nodes), o.vec(g.surface.nodes), o.vec(g.surface.normals);
    o.vec(g.bodies), o.str(g.error);
  }
}

inline void unpack(Unpacker& in, ContactSurfaces& s) {
  in.pod(s.dim), in.pod(s.num_bodies);
  in.vec(s.coords), in.vec(s.global), in.vec(s.copies), in.vec(s.owner), in.vec(s.fixed);
  long long n = 0;
  in.pod(n);
  std::string name;
  for (long long i = 0; i < n; ++i) {
    in.str(name);
    auto& g = s.groups[name];
    in.pod(g.surface.facet_nodes), in.vec(g.surface.nodes), in.vec(g.surface.normals);
    in.vec(g.bodies), in.str(g.error);
  }
}

}  // namespace htfeti
