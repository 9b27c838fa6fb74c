#include "htfeti/io/vtu.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "direct_io.hpp"
#include "htfeti/fem/element.hpp"
#include "htfeti/io/output_file.hpp"

namespace htfeti {

namespace {

using vtu_io::DirectStream;
using vtu_io::write_all;
using vtu_io::WriteBehind;

std::string stem_of(const std::string& path) {
  const auto p = std::filesystem::path(path);
  if (p.extension() == ".vtu" || p.extension() == ".pvtu")
    return (p.parent_path() / p.stem()).string();
  return path;
}

std::string temp_name(const std::string& file) { return temporary_name(file); }

// One data array: name, VTK type, components, raw bytes.
struct Array {
  std::string name, type;
  int components = 1;
  std::string bytes;
};

template <class T>
void write_ascii_values(std::ostream& o, const std::string& bytes) {
  const T* v = reinterpret_cast<const T*>(bytes.data());
  const size_t n = bytes.size() / sizeof(T);
  o.precision(17);
  for (size_t i = 0; i < n; ++i) o << +v[i] << (i + 1 == n ? "\n" : " ");
}

// One subdomain's values of every array (or all of a piece's, for ASCII).
struct Buffers {
  std::vector<double> xyz, u, cf, cg, cp, ct, cs, cst, vm;
  std::vector<std::int64_t> conn, offs;
  std::vector<std::int32_t> conn32, offs32;  // the same, narrowed (Int32 arrays)
  std::vector<std::uint8_t> types;
  std::vector<std::int32_t> sub, clu, rank;
  void clear() {
    xyz.clear(), u.clear(), cf.clear(), cg.clear(), cp.clear(), ct.clear(), cs.clear(),
        cst.clear(), vm.clear(), conn.clear(),
        offs.clear();
    conn32.clear(), offs32.clear(), types.clear(), sub.clear(), clu.clear(), rank.clear();
  }
  void narrow() {
    conn32.assign(conn.begin(), conn.end());
    offs32.assign(offs.begin(), offs.end());
  }
};

// The XML of a piece: the data arrays in the order point data, cell data, points, cells. ASCII:
// the values inline (from the arrays' bytes), and the document closed. Binary: every array
// appended, with `sizes` its bytes; the text ends where the raw data begins ("_").
std::string piece_header(long points, long cells, const std::vector<Array>& point_arrays,
                         const Array& coords, const std::vector<Array>& cell_struct,
                         const std::vector<Array>& cell_arrays, bool ascii,
                         const std::vector<std::uint64_t>& sizes = {}) {
  std::ostringstream o;
  o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
       "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n<Piece "
       "NumberOfPoints=\""
    << points << "\" NumberOfCells=\"" << cells << "\">\n";
  std::uint64_t offset = 0;
  size_t k = 0;
  auto tag = [&](const Array& a) {
    o << "<DataArray type=\"" << a.type << "\" Name=\"" << a.name << "\"";
    if (a.components > 1) o << " NumberOfComponents=\"" << a.components << "\"";
    if (ascii) {
      o << " format=\"ascii\">\n";
      if (a.type == "Float64") write_ascii_values<double>(o, a.bytes);
      if (a.type == "Int64") write_ascii_values<std::int64_t>(o, a.bytes);
      if (a.type == "Int32") write_ascii_values<std::int32_t>(o, a.bytes);
      if (a.type == "UInt8") write_ascii_values<std::uint8_t>(o, a.bytes);
      o << "</DataArray>\n";
    } else {
      o << " format=\"appended\" offset=\"" << offset << "\"/>\n";
      offset += sizeof(std::uint64_t) + sizes.at(k++);
    }
  };
  o << "<PointData>\n";
  for (const auto& a : point_arrays) tag(a);
  o << "</PointData>\n<CellData>\n";
  for (const auto& a : cell_arrays) tag(a);
  o << "</CellData>\n<Points>\n";
  tag(coords);
  o << "</Points>\n<Cells>\n";
  for (const auto& a : cell_struct) tag(a);
  o << "</Cells>\n</Piece>\n</UnstructuredGrid>\n";
  if (ascii)
    o << "</VTKFile>\n";
  else
    o << "<AppendedData encoding=\"raw\">\n_";
  return o.str();
}

void write_ascii_piece(const std::string& file, long points, long cells,
                       const std::vector<Array>& point_arrays, const Array& coords,
                       const std::vector<Array>& cell_struct,
                       const std::vector<Array>& cell_arrays) {
  std::ofstream o(file, std::ios::binary);
  if (!o) throw std::runtime_error("cannot write " + file);
  o << piece_header(points, cells, point_arrays, coords, cell_struct, cell_arrays, true);
  o.flush();
  if (!o) throw std::runtime_error("error while writing " + file + " (disk full?)");
  o.close();
  if (o.fail()) throw std::runtime_error("error while closing " + file);
}

}  // namespace

std::vector<std::string> vtu_files(const std::string& path, int ranks) {
  const std::string stem = stem_of(path);
  if (ranks == 1) return {stem + ".vtu"};
  std::vector<std::string> f{stem + ".pvtu"};
  for (int r = 0; r < ranks; ++r) f.push_back(stem + "_" + std::to_string(r) + ".vtu");
  return f;
}

VtuIo parse_vtu_io(const std::string& name) {
  return parse_name(kVtuIoNames, name, "VTU output mode");
}

std::string to_string(VtuIo value) { return name_of(kVtuIoNames, value); }

namespace {

// The arrays of one rank's piece and where their values come from; write_vtu's steps. Point
// data, cell data, points, cells, in file order (arrays_ points into the members, so a
// PieceWriter is neither copied nor moved).
class PieceWriter {
 public:
  PieceWriter(const Model& model, const std::vector<Eigen::VectorXd>& u,
              std::vector<Eigen::VectorXd> forces, std::vector<Eigen::VectorXd> gaps,
              DualProblem::ContactFields fields, bool contact, bool friction, int rank)
      : model_(model),
        ph_(model.physics()),
        u_(u),
        forces_(std::move(forces)),
        gaps_(std::move(gaps)),
        fields_(std::move(fields)),
        friction_(friction),
        dpn_(ph_.dofs_per_node()),
        elastic_(ph_.kind == PhysicsKind::elasticity),
        contact_(contact),
        rank_(rank) {
    pa_.push_back({"u", "Float64", elastic_ ? 3 : 1, {}});
    if (contact_) {
      pa_.push_back({"contact_force", "Float64", 3, {}});
      pa_.push_back({"contact_gap", "Float64", 1, {}});
      pa_.push_back({"contact_pressure", "Float64", 1, {}});
      if (friction_) {
        pa_.push_back({"tangential_traction", "Float64", 1, {}});
        pa_.push_back({"contact_slip", "Float64", 1, {}});
        pa_.push_back({"contact_state", "Float64", 1, {}});
      }
    }
    ca_ = {{"subdomain", "Int32", 1, {}}, {"cluster", "Int32", 1, {}}, {"rank", "Int32", 1, {}}};
    if (elastic_) ca_.push_back({"von_mises", "Float64", 1, {}});
    cs_ = {
        {"connectivity", "Int64", 1, {}}, {"offsets", "Int64", 1, {}}, {"types", "UInt8", 1, {}}};
    for (auto& a : pa_) arrays_.push_back(&a);
    for (auto& a : ca_) arrays_.push_back(&a);
    arrays_.push_back(&coords_);
    for (auto& a : cs_) arrays_.push_back(&a);
  }
  PieceWriter(const PieceWriter&) = delete;
  PieceWriter& operator=(const PieceWriter&) = delete;

  /// Small outputs: everything in memory, then written as text.
  void write_ascii(const std::vector<int>& subdomains, const std::string& tmp);
  /// Binary, streamed (see the definition); returns the I/O used ("buffered" or "direct").
  std::string write_binary(const std::vector<int>& subdomains, const std::string& piece,
                           const std::string& tmp, const VtuOptions& options);
  /// XDMF: every array (offsets and types aside) as one dataset of the whole mesh in the open
  /// HDF5 file (collective); this rank's values start at its first point and cell.
  void write_hdf5(const std::vector<int>& subdomains, hid_t file, const Comm& comm,
                  std::int64_t& points, std::int64_t& cells, std::string& error);
  /// The XDMF text for datasets in `h5` (a file name beside the XDMF file).
  std::string xdmf_text(const std::string& h5, std::int64_t points, std::int64_t cells,
                        CellType type) const;

 private:
  // Where each subdomain's values start in each array, from the mesh sizes.
  struct Layout {
    std::vector<std::int64_t> nodes, cells, corners;  // prefix sums over the subdomains
    std::int64_t P = 0, C = 0, K = 0;                 // points, cells, corners of the piece
    bool narrow = false;                              // Int32 point ids and offsets
    std::vector<std::uint64_t> sizes, item, start;    // per array: bytes, bytes per item, start
    std::vector<int> place;                    // per array: 0 by points, 1 by cells, 2 by corners
    std::uint64_t end = 0;                     // where the appended data end
    std::uint64_t at(size_t k, int i) const {  // where subdomain i's values of array k begin
      const auto& v = place[k] == 0 ? nodes : place[k] == 1 ? cells : corners;
      return start[k] + item[k] * static_cast<std::uint64_t>(v[i]);
    }
  };
  void fill(int i, const SubdomainMesh& m, std::int64_t base, std::int64_t& off, Buffers& b) const;
  std::pair<const char*, size_t> bytes_of(const Array& a, const Buffers& b) const;
  bool use_int32(std::int64_t points, std::int64_t corners);
  bool by_points(const Array* a) const {  // one value (tuple) per point, else per cell or corner
    return a == &coords_ ||
           std::any_of(pa_.begin(), pa_.end(), [&](const Array& p) { return &p == a; });
  }
  Layout layout(const std::vector<int>& subdomains);
  void fill_checked(const std::vector<int>& subdomains, const Layout& L, int i, Buffers& b) const;
  // The two ways the values reach the file (write_binary); each records its first error.
  void write_positioned(const std::vector<int>& subdomains, const Layout& L,
                        const std::function<void(const char*, size_t, std::uint64_t)>& put,
                        std::string& error) const;
  void write_direct(const std::vector<int>& subdomains, const Layout& L, int fd, int dfd,
                    std::string& error) const;

  const Model& model_;
  const Physics& ph_;
  const std::vector<Eigen::VectorXd>& u_;
  const std::vector<Eigen::VectorXd> forces_, gaps_;
  const DualProblem::ContactFields fields_;
  const bool friction_;
  const int dpn_;
  const bool elastic_, contact_;
  const int rank_;
  std::vector<Array> pa_, ca_, cs_;  // point data, cell data, cells
  Array coords_{"Points", "Float64", 3, {}};
  std::vector<Array*> arrays_;  // all, in file order
};

// The values of the points and cells of subdomain i (mesh m), appended to b (point ids from
// `base`, offsets continuing from `off`).
void PieceWriter::fill(int i, const SubdomainMesh& m, std::int64_t base, std::int64_t& off,
                       Buffers& b) const {
  const int nn = m.num_nodes(), nc = cell_nodes(m.type), ne = m.num_cells();
  const Eigen::VectorXd& u = u_[static_cast<size_t>(i)];
  b.xyz.insert(b.xyz.end(), m.coords.begin(), m.coords.end());
  for (int k = 0; k < nn; ++k) {
    if (!elastic_) {
      b.u.push_back(u[k]);
    } else {
      for (int d = 0; d < 3; ++d) b.u.push_back(d < dpn_ ? u[k * dpn_ + d] : 0.0);
    }
    if (contact_) {
      for (int d = 0; d < 3; ++d) b.cf.push_back(d < dpn_ ? forces_[i][k * dpn_ + d] : 0.0);
      b.cg.push_back(gaps_[i][k]);
      b.cp.push_back(fields_.pressure[i][k]);
      if (friction_) {
        b.ct.push_back(fields_.tangential[i][k]);
        b.cs.push_back(fields_.slip[i][k]);
        b.cst.push_back(fields_.state[i][k]);
      }
    }
  }
  const Eigen::MatrixXd D = elastic_ ? elasticity_matrix(m.dim, ph_.material) : Eigen::MatrixXd();
  for (int e = 0; e < ne; ++e) {
    const int* cn = m.cells.data() + static_cast<size_t>(e) * nc;
    for (int a = 0; a < nc; ++a) b.conn.push_back(base + cn[a]);
    off += nc;
    b.offs.push_back(off);
    b.types.push_back(static_cast<std::uint8_t>(vtk_cell_type(m.type)));
    b.sub.push_back(m.id);
    b.clu.push_back(m.cluster);
    b.rank.push_back(rank_);
    if (elastic_) {
      double x[24];
      Eigen::VectorXd ue(nc * dpn_);
      for (int a = 0; a < nc; ++a) {
        for (int d = 0; d < 3; ++d) x[3 * a + d] = m.coords[3 * static_cast<size_t>(cn[a]) + d];
        for (int d = 0; d < dpn_; ++d) ue[a * dpn_ + d] = u[cn[a] * dpn_ + d];
      }
      const Eigen::VectorXd stress = D * (strain_matrix_at_centroid(m.type, x) * ue);
      b.vm.push_back(von_mises(m.dim, stress, ph_.material.poisson));
    }
  }
}

std::pair<const char*, size_t> PieceWriter::bytes_of(const Array& a, const Buffers& b) const {
  auto raw = [](const auto& v) {
    return std::pair<const char*, size_t>(reinterpret_cast<const char*>(v.data()),
                                          v.size() * sizeof(v[0]));
  };
  if (a.name == "u") return raw(b.u);
  if (a.name == "contact_force") return raw(b.cf);
  if (a.name == "contact_gap") return raw(b.cg);
  if (a.name == "contact_pressure") return raw(b.cp);
  if (a.name == "tangential_traction") return raw(b.ct);
  if (a.name == "contact_slip") return raw(b.cs);
  if (a.name == "contact_state") return raw(b.cst);
  if (a.name == "subdomain") return raw(b.sub);
  if (a.name == "cluster") return raw(b.clu);
  if (a.name == "rank") return raw(b.rank);
  if (a.name == "von_mises") return raw(b.vm);
  if (a.name == "Points") return raw(b.xyz);
  const bool narrow = a.type == "Int32";
  if (a.name == "connectivity") return narrow ? raw(b.conn32) : raw(b.conn);
  if (a.name == "offsets") return narrow ? raw(b.offs32) : raw(b.offs);
  return raw(b.types);
}

// Point ids and offsets as Int32 where the piece's points and cell corners allow (a fifth less
// to write for quadrilaterals; VTK reads either).
bool PieceWriter::use_int32(std::int64_t points, std::int64_t corners) {
  if (points <= INT32_MAX && corners <= INT32_MAX) cs_[0].type = cs_[1].type = "Int32";
  return cs_[0].type == "Int32";
}

void PieceWriter::write_ascii(const std::vector<int>& subdomains, const std::string& tmp) {
  Buffers b;
  std::int64_t base = 0, off = 0;
  for (size_t i = 0; i < subdomains.size(); ++i) {
    const SubdomainMesh m = model_.mesh(subdomains[i]);
    fill(static_cast<int>(i), m, base, off, b);
    base += m.num_nodes();
  }
  if (use_int32(base, off)) b.narrow();
  for (Array* a : arrays_) {
    const auto [data, n] = bytes_of(*a, b);
    a->bytes.assign(data, n);
  }
  write_ascii_piece(tmp, static_cast<long>(base), static_cast<long>(b.types.size()), pa_, coords_,
                    cs_, ca_);
}

// The mesh sizes (Model::mesh_counts, arithmetic on generated boxes) give every array's size and
// every subdomain's place in each array.
PieceWriter::Layout PieceWriter::layout(const std::vector<int>& subdomains) {
  const int ns = static_cast<int>(subdomains.size());
  Layout L;
  L.nodes.assign(ns + 1, 0), L.cells.assign(ns + 1, 0), L.corners.assign(ns + 1, 0);
  std::string merr;
#pragma omp parallel for schedule(dynamic)
  for (int i = 0; i < ns; ++i) {
    try {
      const Model::MeshCounts m = model_.mesh_counts(subdomains[i]);
      L.nodes[i + 1] = m.points, L.cells[i + 1] = m.cells, L.corners[i + 1] = m.corners;
    } catch (const std::exception& e) {
#pragma omp critical
      merr = e.what();
    }
  }
  if (!merr.empty()) throw std::runtime_error(merr);
  for (int i = 0; i < ns; ++i)  // prefix sums: where subdomain i starts
    L.nodes[i + 1] += L.nodes[i], L.cells[i + 1] += L.cells[i], L.corners[i + 1] += L.corners[i];
  L.P = L.nodes[ns], L.C = L.cells[ns], L.K = L.corners[ns];
  L.narrow = use_int32(L.P, L.K);
  for (const Array* a : arrays_) {
    const bool point = by_points(a);
    const std::uint64_t width = a->type == "Float64" || a->type == "Int64" ? 8
                                : a->type == "Int32"                       ? 4
                                                                           : 1;
    const bool corner = a->name == "connectivity";
    const std::int64_t count = point ? L.P : corner ? L.K : L.C;
    L.item.push_back(width * static_cast<std::uint64_t>(a->components));
    L.sizes.push_back(L.item.back() * static_cast<std::uint64_t>(count));
    L.place.push_back(point ? 0 : corner ? 2 : 1);
  }
  return L;
}

// One subdomain's values, checked against the counted sizes.
void PieceWriter::fill_checked(const std::vector<int>& subdomains, const Layout& L, int i,
                               Buffers& b) const {
  b.clear();
  const SubdomainMesh m = model_.mesh(subdomains[i]);
  if (m.num_nodes() != L.nodes[i + 1] - L.nodes[i] ||
      m.num_cells() != L.cells[i + 1] - L.cells[i] ||
      static_cast<std::int64_t>(m.cells.size()) != L.corners[i + 1] - L.corners[i])
    throw std::logic_error("VTU: the mesh of subdomain " + std::to_string(m.id) +
                           " differs from its counted size");
  std::int64_t off = L.corners[i];
  fill(i, m, L.nodes[i], off, b);
  if (L.narrow) b.narrow();
}

// Threads take subdomains and write each array's values to their places.
void PieceWriter::write_positioned(
    const std::vector<int>& subdomains, const Layout& L,
    const std::function<void(const char*, size_t, std::uint64_t)>& put, std::string& error) const {
  const int ns = static_cast<int>(subdomains.size());
#pragma omp parallel
  {
    Buffers b;
#pragma omp for schedule(dynamic)
    for (int i = 0; i < ns; ++i) {
      try {
        fill_checked(subdomains, L, i, b);
        for (size_t k = 0; k < arrays_.size(); ++k) {
          const auto [data, n] = bytes_of(*arrays_[k], b);
          put(data, n, L.at(k, i));
        }
      } catch (const std::exception& e) {
#pragma omp critical
        error = e.what();
      }
    }
  }
}

// Each thread takes a contiguous run of subdomains (split by points), so that its values of each
// array are one contiguous range of the file, appended in subdomain order; one background
// thread writes the filled stages.
void PieceWriter::write_direct(const std::vector<int>& subdomains, const Layout& L, int fd, int dfd,
                               std::string& error) const {
  const int ns = static_cast<int>(subdomains.size());
  {
    WriteBehind writer(fd, dfd);
#pragma omp parallel
    {
      const int nt = omp_get_num_threads(), t = omp_get_thread_num();
      auto split = [&](int part) {  // the first subdomain of thread `part`
        return static_cast<int>(
            std::lower_bound(L.nodes.begin(), L.nodes.end() - 1, L.P * part / nt) -
            L.nodes.begin());
      };
      const int lo = split(t), hi = t + 1 == nt ? ns : split(t + 1);
      try {
        std::vector<DirectStream> streams;
        streams.reserve(arrays_.size());
        for (size_t k = 0; k < arrays_.size(); ++k)
          streams.emplace_back(fd, writer, L.at(k, lo), L.at(k, hi));
        Buffers b;
        for (int i = lo; i < hi; ++i) {
          fill_checked(subdomains, L, i, b);
          for (size_t k = 0; k < arrays_.size(); ++k) {
            const auto [data, n] = bytes_of(*arrays_[k], b);
            streams[k].append(data, n);
          }
        }
        for (auto& s : streams) s.finish();
      } catch (const std::exception& e) {
#pragma omp critical
        error = e.what();
      }
    }
  }  // the writer's thread has ended: every stage is on the disk
  ::close(dfd);
}

// Binary, streamed: the layout gives every array's size and every subdomain's place in each
// array, so the header (with the offsets of the appended data) is written first; then threads
// take subdomains and write their values to their places in the file by positioned writes (or
// through direct I/O). Memory: one subdomain's buffers per thread.
std::string PieceWriter::write_binary(const std::vector<int>& subdomains, const std::string& piece,
                                      const std::string& tmp, const VtuOptions& options) {
  Layout L = layout(subdomains);
  const std::string head = piece_header(static_cast<long>(L.P), static_cast<long>(L.C), pa_,
                                        coords_, cs_, ca_, false, L.sizes);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) throw std::runtime_error("cannot write " + tmp);
  std::string werr;
  auto put = [&](const char* data, size_t n, std::uint64_t at) {
    if (!write_all(fd, data, n, at)) {
#pragma omp critical
      werr = "error while writing " + piece + " (disk full?)";
    }
  };
  put(head.data(), head.size(), 0);
  std::uint64_t at = head.size();
  for (size_t k = 0; k < arrays_.size(); ++k) {
    put(reinterpret_cast<const char*>(&L.sizes[k]), sizeof(std::uint64_t), at);
    L.start.push_back(at + sizeof(std::uint64_t));
    at += sizeof(std::uint64_t) + L.sizes[k];
  }
  L.end = at;
  const std::string tail = "\n</AppendedData>\n</VTKFile>\n";
  put(tail.data(), tail.size(), at);
  // Direct I/O: the same file opened a second time with O_DIRECT (refused by some file systems,
  // tmpfs on older kernels for one: then everything goes through `fd`).
  const bool want_direct =
      options.io == VtuIo::direct ||
      (options.io == VtuIo::automatic && static_cast<double>(at) >= VtuOptions::kDirectMinBytes);
  const int dfd = want_direct ? ::open(tmp.c_str(), O_WRONLY | O_DIRECT) : -1;
  if (dfd < 0)
    write_positioned(subdomains, L, put, werr);
  else
    write_direct(subdomains, L, fd, dfd, werr);
  if (::close(fd) != 0 && werr.empty()) werr = "error while closing " + piece;
  if (!werr.empty()) throw std::runtime_error(werr);
  return dfd >= 0 ? "direct" : "buffered";
}

// HDF5 calls return a negative value or id on failure (their error stack printing is off).
hid_t h5_check(hid_t id, const char* what) {
  if (id < 0) throw std::runtime_error(std::string("HDF5: ") + what + " failed");
  return id;
}

hid_t h5_type(const std::string& vtk_type) {
  return vtk_type == "Float64" ? H5T_NATIVE_DOUBLE
         : vtk_type == "Int32" ? H5T_NATIVE_INT32
                               : H5T_NATIVE_INT64;
}

// Dataset names: the VTU array names, "points" and "cells" for the mesh.
std::string h5_name(const std::string& vtu_name) {
  return vtu_name == "Points" ? "points" : vtu_name == "connectivity" ? "cells" : vtu_name;
}

// Each array becomes a dataset [points or cells] x [components] (cells: [cells] x [corners per
// cell], global point ids). Dataset creation and the file's closing are collective; the values
// are written subdomain by subdomain with independent transfers, one hyperslab each.
void PieceWriter::write_hdf5(const std::vector<int>& subdomains, hid_t file, const Comm& comm,
                             std::int64_t& points, std::int64_t& cells, std::string& error) {
  const int ns = static_cast<int>(subdomains.size());
  std::vector<std::int64_t> nodes(ns + 1, 0), cellc(ns + 1, 0);
  int corners = 0;
  try {
    for (int i = 0; i < ns; ++i) {
      const Model::MeshCounts m = model_.mesh_counts(subdomains[i]);
      nodes[i + 1] = nodes[i] + m.points, cellc[i + 1] = cellc[i] + m.cells;
      if (m.cells > 0) corners = static_cast<int>(m.corners / m.cells);
    }
  } catch (const std::exception& e) {
    error = e.what();
  }
  corners = static_cast<int>(comm.max(static_cast<double>(corners)));
  long long first[2] = {nodes[ns], cellc[ns]}, total[2] = {0, 0};
  MPI_Exscan(MPI_IN_PLACE, first, 2, MPI_LONG_LONG, MPI_SUM, comm.raw());
  if (comm.rank() == 0) first[0] = first[1] = 0;
  total[0] = comm.sum(static_cast<long long>(nodes[ns]));
  total[1] = comm.sum(static_cast<long long>(cellc[ns]));
  points = total[0], cells = total[1];
  std::vector<const Array*> arrays;  // (offsets and types are VTK's cell layout, not needed)
  for (const Array* a : arrays_)
    if (a->name != "offsets" && a->name != "types") arrays.push_back(a);
  std::vector<hid_t> sets, types;
  std::vector<char> by_point;
  for (const Array* a : arrays) {
    const bool point = by_points(a);
    const int width = a->name == "connectivity" ? corners : a->components;
    const hsize_t dims[2] = {static_cast<hsize_t>(point ? total[0] : total[1]),
                             static_cast<hsize_t>(width)};
    const hid_t space = h5_check(H5Screate_simple(2, dims, nullptr), "H5Screate_simple");
    types.push_back(h5_type(a->name == "connectivity" ? "Int64" : a->type));
    by_point.push_back(point);
    sets.push_back(h5_check(H5Dcreate2(file, h5_name(a->name).c_str(), types.back(), space,
                                       H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                            "H5Dcreate2"));
    H5Sclose(space);
  }
  Buffers b;
  for (int i = 0; i < ns && error.empty(); ++i) {
    try {
      b.clear();
      const SubdomainMesh m = model_.mesh(subdomains[i]);
      if (m.num_nodes() != nodes[i + 1] - nodes[i] || m.num_cells() != cellc[i + 1] - cellc[i])
        throw std::logic_error("XDMF: the mesh of subdomain " + std::to_string(m.id) +
                               " differs from its counted size");
      std::int64_t off = 0;
      fill(i, m, first[0] + nodes[i], off, b);  // point ids: global
      for (size_t k = 0; k < arrays.size(); ++k) {
        const Array& a = *arrays[k];
        const auto [data, bytes] =
            a.name == "connectivity"
                ? std::pair<const char*, size_t>(reinterpret_cast<const char*>(b.conn.data()),
                                                 b.conn.size() * sizeof(std::int64_t))
                : bytes_of(a, b);
        const bool point = by_point[k];
        const hsize_t start[2] = {
            static_cast<hsize_t>(point ? first[0] + nodes[i] : first[1] + cellc[i]), 0};
        const hsize_t count[2] = {
            static_cast<hsize_t>(point ? nodes[i + 1] - nodes[i] : cellc[i + 1] - cellc[i]),
            static_cast<hsize_t>(a.name == "connectivity" ? corners : a.components)};
        if (count[0] == 0) continue;
        if (bytes != count[0] * count[1] * H5Tget_size(types[k]))
          throw std::logic_error("XDMF: array " + a.name + " has an unexpected size");
        const hid_t space = h5_check(H5Dget_space(sets[k]), "H5Dget_space");
        H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
        const hid_t mem = h5_check(H5Screate_simple(2, count, nullptr), "H5Screate_simple");
        const herr_t status = H5Dwrite(sets[k], types[k], mem, space, H5P_DEFAULT, data);
        H5Sclose(mem), H5Sclose(space);
        if (status < 0) throw std::runtime_error("HDF5: writing " + a.name + " failed");
      }
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  for (hid_t s : sets) H5Dclose(s);
}

std::string PieceWriter::xdmf_text(const std::string& h5, std::int64_t points, std::int64_t cells,
                                   CellType type) const {
  const char* topology = type == CellType::tri3    ? "Triangle"
                         : type == CellType::quad4 ? "Quadrilateral"
                         : type == CellType::tet4  ? "Tetrahedron"
                                                   : "Hexahedron";
  std::ostringstream o;
  auto item = [&](std::int64_t rows, int columns, const std::string& vtk_type,
                  const std::string& name) {
    const bool real = vtk_type == "Float64";
    o << "<DataItem Dimensions=\"" << rows << " " << columns << "\" NumberType=\""
      << (real ? "Float" : "Int") << "\" Precision=\"" << (vtk_type == "Int32" ? 4 : 8)
      << "\" Format=\"HDF\">" << h5 << ":/" << name << "</DataItem>\n";
  };
  o << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
       "<Xdmf Version=\"2.0\">\n<Domain>\n<Grid Name=\"htfeti\" GridType=\"Uniform\">\n"
    << "<Topology TopologyType=\"" << topology << "\" NumberOfElements=\"" << cells << "\">\n";
  item(cells, cell_nodes(type), "Int64", "cells");
  o << "</Topology>\n<Geometry GeometryType=\"XYZ\">\n";
  item(points, 3, "Float64", "points");
  o << "</Geometry>\n";
  for (const auto* group : {&pa_, &ca_})
    for (const Array& a : *group) {
      o << "<Attribute Name=\"" << a.name << "\" AttributeType=\""
        << (a.components == 3 ? "Vector" : "Scalar") << "\" Center=\""
        << (group == &pa_ ? "Node" : "Cell") << "\">\n";
      item(group == &pa_ ? points : cells, a.components, a.type, a.name);
      o << "</Attribute>\n";
    }
  o << "</Grid>\n</Domain>\n</Xdmf>\n";
  return o.str();
}

// The parallel file that lists the ranks' pieces (rank 0, several ranks).
void write_pvtu(const std::string& tmp, const std::vector<std::string>& files, bool elastic,
                bool friction,
                bool contact) {
  std::ofstream o(tmp);
  if (!o) throw std::runtime_error("cannot write " + files[0]);
  o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" "
       "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PUnstructuredGrid "
       "GhostLevel=\"0\">\n<PPointData>\n<PDataArray type=\"Float64\" Name=\"u\""
    << (elastic ? " NumberOfComponents=\"3\"" : "") << "/>\n";
  if (contact)
    o << "<PDataArray type=\"Float64\" Name=\"contact_force\" NumberOfComponents=\"3\"/>\n"
      << "<PDataArray type=\"Float64\" Name=\"contact_gap\"/>\n"
      << "<PDataArray type=\"Float64\" Name=\"contact_pressure\"/>\n";
  if (friction)
    o << "<PDataArray type=\"Float64\" Name=\"tangential_traction\"/>\n"
      << "<PDataArray type=\"Float64\" Name=\"contact_slip\"/>\n"
      << "<PDataArray type=\"Float64\" Name=\"contact_state\"/>\n";
  o << "</PPointData>\n<PCellData>\n<PDataArray type=\"Int32\" Name=\"subdomain\"/>\n"
       "<PDataArray type=\"Int32\" Name=\"cluster\"/>\n<PDataArray type=\"Int32\" "
       "Name=\"rank\"/>\n";
  if (elastic) o << "<PDataArray type=\"Float64\" Name=\"von_mises\"/>\n";
  o << "</PCellData>\n<PPoints><PDataArray type=\"Float64\" "
       "NumberOfComponents=\"3\"/></PPoints>\n";
  for (size_t r = 1; r < files.size(); ++r)
    o << "<Piece Source=\"" << std::filesystem::path(files[r]).filename().string() << "\"/>\n";
  o << "</PUnstructuredGrid>\n</VTKFile>\n";
  o.flush();
  if (!o) throw std::runtime_error("error while writing " + files[0]);
}

// The writer of this rank's subdomains (listed in `subdomains`), with the contact fields
// computed first (collective, in this order on every rank).
std::unique_ptr<PieceWriter> make_writer(const Model& model, DualProblem& dual,
                                         const std::vector<Eigen::VectorXd>& u,
                                         const Eigen::VectorXd& lambda,
                                         std::vector<int>& subdomains) {
  subdomains.clear();
  for (const auto& s : dual.subdomains()) subdomains.push_back(s->id());
  auto forces = dual.contact_forces(lambda);
  auto gaps = dual.contact_gap_field(u);
  auto fields = dual.contact_fields(u, lambda);
  return std::make_unique<PieceWriter>(model, u, std::move(forces), std::move(gaps),
                                       std::move(fields), dual.has_inequalities(),
                                       dual.has_friction(), dual.comm().rank());
}

// Every rank's error agreed on; on one, `temporaries` (this rank's) are removed and it throws.
void agree_or_remove(const Comm& comm, const std::string& error,
                     const std::vector<std::string>& temporaries) {
  try {
    comm.agree(error);
  } catch (...) {
    std::error_code ec;
    for (const auto& f : temporaries) std::filesystem::remove(f, ec);
    throw;
  }
}

}  // namespace

// The fields are computed first (collective), then every rank writes its piece under a temporary
// name, rank 0 the .pvtu; the ranks agree on any failure, and only then rename the files into
// place (a failed run leaves nothing behind).
VtuWritten write_vtu(const std::string& path, const Model& model, DualProblem& dual,
                     const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda,
                     const VtuOptions& options) {
  VtuWritten written;
  written.io = options.ascii ? "ascii" : "buffered";
  const Comm& comm = dual.comm();
  const auto files = vtu_files(path, comm.size());
  const std::string piece = comm.size() == 1 ? files[0] : files[1 + comm.rank()];
  const std::string piece_tmp = temp_name(piece);
  const bool elastic = model.physics().kind == PhysicsKind::elasticity;
  const bool contact = dual.has_inequalities();
  std::vector<int> subdomains;
  const auto made = make_writer(model, dual, u, lambda, subdomains);
  PieceWriter& writer = *made;
  std::string error;
  try {
    if (options.ascii)
      writer.write_ascii(subdomains, piece_tmp);
    else
      written.io = writer.write_binary(subdomains, piece, piece_tmp, options);
    if (comm.size() > 1 && comm.rank() == 0)
      write_pvtu(temp_name(files[0]), files, elastic, dual.has_friction(), contact);
  } catch (const std::exception& e) {
    error = e.what();
  }
  std::vector<std::string> temporaries{piece_tmp};
  if (comm.rank() == 0 && comm.size() > 1) temporaries.push_back(temp_name(files[0]));
  agree_or_remove(comm, error, temporaries);
  std::error_code ec;
  std::filesystem::rename(piece_tmp, piece, ec);
  if (!ec && comm.rank() == 0 && comm.size() > 1)
    std::filesystem::rename(temp_name(files[0]), files[0], ec);
  comm.agree(ec ? "cannot rename the output to " + piece + ": " + ec.message() : "");
  written.path = files[0];
  return written;
}

std::vector<std::string> xdmf_files(const std::string& path) {
  std::filesystem::path h5(path);
  h5.replace_extension(".h5");
  return {path, h5.string()};
}

// As write_vtu: the fields first (collective), then the HDF5 file under a temporary name, written
// by all ranks through MPI-IO, and the XDMF text by rank 0; renamed into place only when every
// rank succeeded.
void write_xdmf(const std::string& path, const Model& model, DualProblem& dual,
                const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda) {
  const Comm& comm = dual.comm();
  const auto files = xdmf_files(path);
  // One temporary name on every rank (temporary names carry the process id): rank 0's.
  const std::string xdmf_tmp = temp_name(files[0]);
  std::string h5_tmp = temp_name(files[1]);
  int length = static_cast<int>(h5_tmp.size());
  MPI_Bcast(&length, 1, MPI_INT, 0, comm.raw());
  h5_tmp.resize(static_cast<size_t>(length));
  MPI_Bcast(h5_tmp.data(), length, MPI_CHAR, 0, comm.raw());
  std::vector<int> subdomains;
  const auto made = make_writer(model, dual, u, lambda, subdomains);
  PieceWriter& writer = *made;
  int type = subdomains.empty() ? -1 : static_cast<int>(model.mesh(subdomains[0]).type);
  type = static_cast<int>(comm.max(static_cast<double>(type)));
  std::string error;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_fapl_mpio(fapl, comm.raw(), MPI_INFO_NULL);
  const hid_t file = H5Fcreate(h5_tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  comm.agree(file < 0 ? "cannot create " + files[1] : "");  // (H5Fcreate is collective)
  std::int64_t points = 0, cells = 0;
  try {
    writer.write_hdf5(subdomains, file, comm, points, cells, error);
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (H5Fclose(file) < 0 && error.empty()) error = "error while writing " + files[1];
  if (error.empty() && comm.rank() == 0) {
    try {
      write_atomically(xdmf_tmp,
                       writer.xdmf_text(std::filesystem::path(files[1]).filename().string(), points,
                                        cells, static_cast<CellType>(type)));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  agree_or_remove(
      comm, error,
      comm.rank() == 0 ? std::vector<std::string>{h5_tmp, xdmf_tmp} : std::vector<std::string>{});
  std::error_code ec;
  if (comm.rank() == 0) {
    std::filesystem::rename(h5_tmp, files[1], ec);
    if (!ec) std::filesystem::rename(xdmf_tmp, files[0], ec);
  }
  comm.agree(ec ? "cannot rename the output to " + files[0] + ": " + ec.message() : "");
}

}  // namespace htfeti
