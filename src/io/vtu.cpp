#include "htfeti/io/vtu.hpp"

#include <fcntl.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "htfeti/fem/element.hpp"
#include "htfeti/io/output_file.hpp"

namespace htfeti {

namespace {

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
  std::vector<double> xyz, u, cf, cg, vm;
  std::vector<std::int64_t> conn, offs;
  std::vector<std::int32_t> conn32, offs32;  // the same, narrowed (Int32 arrays)
  std::vector<std::uint8_t> types;
  std::vector<std::int32_t> sub, clu, rank;
  void clear() {
    xyz.clear(), u.clear(), cf.clear(), cg.clear(), vm.clear(), conn.clear(), offs.clear();
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

// Writes n bytes at `at` with positioned writes (a write may take less than asked); false on an
// error (disk full, I/O error).
bool write_all(int fd, const char* data, size_t n, std::uint64_t at) {
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, data, n, static_cast<off_t>(at));
    if (w <= 0) return false;
    data += w, n -= static_cast<size_t>(w), at += static_cast<std::uint64_t>(w);
  }
  return true;
}

// Background writes of whole staged blocks by direct I/O: one thread that takes the filled
// stages of every stream in the order they were handed over and writes them with positioned
// writes, so that the threads that fill the stages (meshes, values) do not wait for the disk
// while it has work. A stage is handed over with a flag that the writer clears when the stage
// is on the disk (or failed); its owner waits for that flag before it fills the stage again.
class WriteBehind {
 public:
  WriteBehind(int fd, int dfd) : fd_(fd), dfd_(dfd), thread_([this] { run(); }) {}
  ~WriteBehind() {
    {
      std::lock_guard<std::mutex> l(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  WriteBehind(const WriteBehind&) = delete;
  WriteBehind& operator=(const WriteBehind&) = delete;

  void submit(const char* data, size_t n, std::uint64_t at, bool* in_flight) {
    {
      std::lock_guard<std::mutex> l(m_);
      *in_flight = true;
      jobs_.push_back({data, n, at, in_flight});
    }
    cv_.notify_all();
  }
  void wait(const bool* in_flight) {
    std::unique_lock<std::mutex> l(m_);
    cv_.wait(l, [&] { return !*in_flight; });
  }
  std::string error() {
    std::lock_guard<std::mutex> l(m_);
    return error_;
  }

 private:
  struct Job {
    const char* data;
    size_t n;
    std::uint64_t at;
    bool* in_flight;
  };
  void run() {
    std::unique_lock<std::mutex> l(m_);
    for (;;) {
      cv_.wait(l, [&] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // stop_ and nothing left
      const Job j = jobs_.front();
      jobs_.pop_front();
      const bool skip = !error_.empty();  // after an error the rest is not written
      l.unlock();
      const bool ok = skip || write(j);
      l.lock();
      if (!ok && error_.empty()) error_ = "error while writing the VTU (disk full?)";
      *j.in_flight = false;
      cv_.notify_all();
    }
  }
  bool write(const Job& j) const {
    size_t done = 0;
    while (done < j.n) {
      const ssize_t w = ::pwrite(dfd_, j.data + done, j.n - done, static_cast<off_t>(j.at + done));
      if (w < 0 && errno == EINVAL)  // direct I/O refused here: the page cache
        return write_all(fd_, j.data + done, j.n - done, j.at + done);
      if (w <= 0) return false;
      done += static_cast<size_t>(w);
    }
    return true;
  }
  int fd_, dfd_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<Job> jobs_;
  std::string error_;
  bool stop_ = false;
  std::thread thread_;  // last: started after the members it uses
};

// One thread's values of one array: the contiguous byte range [begin, end) of the file, appended
// in order. The 4 KiB blocks wholly inside the range go to the file by direct I/O from two
// aligned staging buffers of a MiB: one is filled while the other is written (WriteBehind). The
// bytes before the range's first block boundary and after its last lie in blocks shared with
// the neighbouring ranges and are written through the page cache (`fd`), as is everything when
// the direct write is refused (EINVAL).
class DirectStream {
 public:
  static constexpr std::uint64_t kBlock = 4096, kStage = std::uint64_t{1} << 20;
  DirectStream(int fd, WriteBehind& writer, std::uint64_t begin, std::uint64_t end)
      : fd_(fd), writer_(&writer), pos_(begin), end_(end) {
    lo_ = (begin + kBlock - 1) / kBlock * kBlock;
    hi_ = end / kBlock * kBlock;
    if (hi_ <= lo_) lo_ = hi_ = end;  // no whole block: all through the page cache
    stage_at_ = lo_;
  }
  DirectStream(DirectStream&& o) noexcept
      : fd_(o.fd_),
        writer_(o.writer_),
        pos_(o.pos_),
        end_(o.end_),
        lo_(o.lo_),
        hi_(o.hi_),
        stage_at_(o.stage_at_),
        fill_(o.fill_),
        cur_(o.cur_) {
    for (int s = 0; s < 2; ++s) {  // moved before any write (vector growth): nothing in flight
      stage_[s] = std::move(o.stage_[s]);
      in_flight_[s] = false;
    }
    o.writer_ = nullptr;
  }
  DirectStream(const DirectStream&) = delete;
  DirectStream& operator=(const DirectStream&) = delete;
  DirectStream& operator=(DirectStream&&) = delete;
  ~DirectStream() {  // the stages must stay until the writer is done with them
    if (writer_)
      for (int s = 0; s < 2; ++s) writer_->wait(&in_flight_[s]);
  }

  void append(const char* data, size_t n) {
    if (pos_ + n > end_) throw std::logic_error("VTU: a piece's values overrun their range");
    while (n > 0) {
      if (pos_ < lo_ || pos_ >= hi_) {  // a partial block at either end
        const size_t k =
            static_cast<size_t>(std::min<std::uint64_t>(n, (pos_ < lo_ ? lo_ : end_) - pos_));
        buffered(data, k, pos_);
        data += k, n -= k, pos_ += k;
        continue;
      }
      if (!stage_[cur_]) {
        stage_[cur_].reset(static_cast<char*>(std::aligned_alloc(kBlock, kStage)));
        if (!stage_[cur_]) throw std::bad_alloc();
      }
      const size_t k =
          static_cast<size_t>(std::min<std::uint64_t>({n, kStage - fill_, hi_ - pos_}));
      std::memcpy(stage_[cur_].get() + fill_, data, k);
      fill_ += k, data += k, n -= k, pos_ += k;
      if (fill_ == kStage || pos_ == hi_) hand_over();
    }
  }
  /// Waits until this stream's values are on the disk; throws on a write error.
  void finish() {
    if (pos_ != end_) throw std::logic_error("VTU: a piece's values fall short of their range");
    for (int s = 0; s < 2; ++s) writer_->wait(&in_flight_[s]);
    const std::string e = writer_->error();
    if (!e.empty()) throw std::runtime_error(e);
  }

 private:
  void buffered(const char* data, size_t n, std::uint64_t at) {
    if (!write_all(fd_, data, n, at))
      throw std::runtime_error("error while writing the VTU (disk full?)");
  }
  void hand_over() {  // fill_ is a whole number of blocks here
    writer_->submit(stage_[cur_].get(), fill_, stage_at_, &in_flight_[cur_]);
    stage_at_ += fill_;
    fill_ = 0;
    cur_ ^= 1;
    writer_->wait(&in_flight_[cur_]);  // the other stage: free once its write is done
  }
  int fd_;
  WriteBehind* writer_;
  std::uint64_t pos_, end_, lo_ = 0, hi_ = 0, stage_at_ = 0;
  size_t fill_ = 0;
  int cur_ = 0;  // the stage being filled
  struct Free {
    void operator()(char* p) const { std::free(p); }
  };
  std::unique_ptr<char[], Free> stage_[2];  // aligned_alloc'd, kStage bytes, made on first use
  bool in_flight_[2] = {false, false};      // guarded by the writer's mutex
};

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

VtuWritten write_vtu(const std::string& path, const Model& model, DualProblem& dual,
                     const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda,
                     const VtuOptions& options) {
  VtuWritten written;
  written.io = options.ascii ? "ascii" : "buffered";
  const Comm& comm = dual.comm();
  const auto files = vtu_files(path, comm.size());
  const std::string piece = comm.size() == 1 ? files[0] : files[1 + comm.rank()];
  const std::string piece_tmp = temp_name(piece);
  const Physics& ph = model.physics();
  const int dpn = ph.dofs_per_node();
  const bool elastic = ph.kind == PhysicsKind::elasticity;
  const auto forces = dual.contact_forces(lambda);
  const auto gaps = dual.contact_gap_field(u);
  const bool contact = dual.has_inequalities();
  std::string error;
  try {
    const auto& subs = dual.subdomains();
    // The values of subdomain i's points and cells, appended to b (point ids from `base`,
    // offsets continuing from `off`).
    auto fill = [&](size_t i, const SubdomainMesh& m, std::int64_t base, std::int64_t& off,
                    Buffers& b) {
      const int nn = m.num_nodes(), nc = cell_nodes(m.type), ne = m.num_cells();
      b.xyz.insert(b.xyz.end(), m.coords.begin(), m.coords.end());
      for (int k = 0; k < nn; ++k) {
        if (!elastic) {
          b.u.push_back(u[i][k]);
        } else {
          for (int d = 0; d < 3; ++d) b.u.push_back(d < dpn ? u[i][k * dpn + d] : 0.0);
        }
        if (contact) {
          for (int d = 0; d < 3; ++d) b.cf.push_back(d < dpn ? forces[i][k * dpn + d] : 0.0);
          b.cg.push_back(gaps[i][k]);
        }
      }
      const Eigen::MatrixXd D = elastic ? elasticity_matrix(m.dim, ph.material) : Eigen::MatrixXd();
      for (int e = 0; e < ne; ++e) {
        const int* cn = m.cells.data() + static_cast<size_t>(e) * nc;
        for (int a = 0; a < nc; ++a) b.conn.push_back(base + cn[a]);
        off += nc;
        b.offs.push_back(off);
        b.types.push_back(static_cast<std::uint8_t>(vtk_cell_type(m.type)));
        b.sub.push_back(m.id);
        b.clu.push_back(m.cluster);
        b.rank.push_back(comm.rank());
        if (elastic) {
          double x[24];
          Eigen::VectorXd ue(nc * dpn);
          for (int a = 0; a < nc; ++a) {
            for (int d = 0; d < 3; ++d) x[3 * a + d] = m.coords[3 * static_cast<size_t>(cn[a]) + d];
            for (int d = 0; d < dpn; ++d) ue[a * dpn + d] = u[i][cn[a] * dpn + d];
          }
          const Eigen::VectorXd stress = D * (strain_matrix_at_centroid(m.type, x) * ue);
          b.vm.push_back(von_mises(m.dim, stress, ph.material.poisson));
        }
      }
    };
    std::vector<Array> pa{{"u", "Float64", elastic ? 3 : 1, {}}};
    if (contact) {
      pa.push_back({"contact_force", "Float64", 3, {}});
      pa.push_back({"contact_gap", "Float64", 1, {}});
    }
    std::vector<Array> ca{
        {"subdomain", "Int32", 1, {}}, {"cluster", "Int32", 1, {}}, {"rank", "Int32", 1, {}}};
    if (elastic) ca.push_back({"von_mises", "Float64", 1, {}});
    Array coords{"Points", "Float64", 3, {}};
    std::vector<Array> cs{
        {"connectivity", "Int64", 1, {}}, {"offsets", "Int64", 1, {}}, {"types", "UInt8", 1, {}}};
    // Point ids and offsets as Int32 where the piece's points and cell corners allow (a fifth
    // less to write for quadrilaterals; VTK reads either).
    auto use_int32 = [&](std::int64_t points, std::int64_t corners) {
      if (points <= INT32_MAX && corners <= INT32_MAX) cs[0].type = cs[1].type = "Int32";
      return cs[0].type == "Int32";
    };
    // The arrays in file order, each with its source in the buffers.
    std::vector<Array*> arrays;
    for (auto& a : pa) arrays.push_back(&a);
    for (auto& a : ca) arrays.push_back(&a);
    arrays.push_back(&coords);
    for (auto& a : cs) arrays.push_back(&a);
    auto bytes_of = [&](const Array& a, const Buffers& b) -> std::pair<const char*, size_t> {
      auto raw = [](const auto& v) {
        return std::pair<const char*, size_t>(reinterpret_cast<const char*>(v.data()),
                                              v.size() * sizeof(v[0]));
      };
      if (a.name == "u") return raw(b.u);
      if (a.name == "contact_force") return raw(b.cf);
      if (a.name == "contact_gap") return raw(b.cg);
      if (a.name == "subdomain") return raw(b.sub);
      if (a.name == "cluster") return raw(b.clu);
      if (a.name == "rank") return raw(b.rank);
      if (a.name == "von_mises") return raw(b.vm);
      if (a.name == "Points") return raw(b.xyz);
      const bool narrow = a.type == "Int32";
      if (a.name == "connectivity") return narrow ? raw(b.conn32) : raw(b.conn);
      if (a.name == "offsets") return narrow ? raw(b.offs32) : raw(b.offs);
      return raw(b.types);
    };
    if (options.ascii) {  // small outputs: everything in memory, then written as text
      Buffers b;
      std::int64_t base = 0, off = 0;
      for (size_t i = 0; i < subs.size(); ++i) {
        const SubdomainMesh m = model.mesh(subs[i]->id());
        fill(i, m, base, off, b);
        base += m.num_nodes();
      }
      if (use_int32(base, off)) b.narrow();
      for (Array* a : arrays) {
        const auto [data, n] = bytes_of(*a, b);
        a->bytes.assign(data, n);
      }
      write_ascii_piece(piece_tmp, static_cast<long>(base), static_cast<long>(b.types.size()), pa,
                        coords, cs, ca);
    } else {
      // Binary, streamed: the mesh sizes (Model::mesh_counts, arithmetic on generated boxes) give
      // every array's size and every subdomain's place in each array, so the header (with the
      // offsets of the appended data) is written first; then threads take subdomains and write
      // their values to their places in the file by positioned writes. Memory: one subdomain's
      // buffers per thread.
      const int ns = static_cast<int>(subs.size());
      std::vector<std::int64_t> nodes(ns + 1, 0), cells(ns + 1, 0), corners(ns + 1, 0);
      std::string merr;
#pragma omp parallel for schedule(dynamic)
      for (int i = 0; i < ns; ++i) {
        try {
          const Model::MeshCounts m = model.mesh_counts(subs[i]->id());
          nodes[i + 1] = m.points, cells[i + 1] = m.cells, corners[i + 1] = m.corners;
        } catch (const std::exception& e) {
#pragma omp critical
          merr = e.what();
        }
      }
      if (!merr.empty()) throw std::runtime_error(merr);
      for (int i = 0; i < ns; ++i)  // prefix sums: where subdomain i starts
        nodes[i + 1] += nodes[i], cells[i + 1] += cells[i], corners[i + 1] += corners[i];
      const std::int64_t P = nodes[ns], C = cells[ns], K = corners[ns];
      const bool narrow = use_int32(P, K);
      std::vector<std::uint64_t> sizes, item;  // bytes of each array, bytes per point/cell/corner
      std::vector<const std::vector<std::int64_t>*> index;  // the prefix sums that place it
      for (const Array* a : arrays) {
        const bool point = a == &coords || a->name == "u" || a->name == "contact_force" ||
                           a->name == "contact_gap";
        const std::uint64_t width = a->type == "Float64" || a->type == "Int64" ? 8
                                    : a->type == "Int32"                       ? 4
                                                                               : 1;
        const bool corner = a->name == "connectivity";
        const std::int64_t count = point ? P : corner ? K : C;
        item.push_back(width * static_cast<std::uint64_t>(a->components));
        sizes.push_back(item.back() * static_cast<std::uint64_t>(count));
        index.push_back(point ? &nodes : corner ? &corners : &cells);
      }
      const std::string head = piece_header(static_cast<long>(P), static_cast<long>(C), pa, coords,
                                            cs, ca, false, sizes);
      const int fd = ::open(piece_tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0) throw std::runtime_error("cannot write " + piece_tmp);
      std::string werr;
      auto put = [&](const char* data, size_t n, std::uint64_t at) {
        if (!write_all(fd, data, n, at)) {
#pragma omp critical
          werr = "error while writing " + piece + " (disk full?)";
        }
      };
      put(head.data(), head.size(), 0);
      std::vector<std::uint64_t> start;  // where each array's values begin
      std::uint64_t at = head.size();
      for (size_t k = 0; k < arrays.size(); ++k) {
        put(reinterpret_cast<const char*>(&sizes[k]), sizeof(std::uint64_t), at);
        start.push_back(at + sizeof(std::uint64_t));
        at += sizeof(std::uint64_t) + sizes[k];
      }
      const std::string tail = "\n</AppendedData>\n</VTKFile>\n";
      put(tail.data(), tail.size(), at);
      // Direct I/O: the same file opened a second time with O_DIRECT (refused by some file
      // systems, tmpfs on older kernels for one: then everything goes through `fd`).
      const bool want_direct =
          options.io == VtuIo::direct || (options.io == VtuIo::automatic &&
                                          static_cast<double>(at) >= VtuOptions::kDirectMinBytes);
      const int dfd = want_direct ? ::open(piece_tmp.c_str(), O_WRONLY | O_DIRECT) : -1;
      if (dfd >= 0) written.io = "direct";
      // One subdomain's values, checked against the counted sizes.
      auto fill_checked = [&](int i, Buffers& b) {
        b.clear();
        const SubdomainMesh m = model.mesh(subs[i]->id());
        if (m.num_nodes() != nodes[i + 1] - nodes[i] || m.num_cells() != cells[i + 1] - cells[i] ||
            static_cast<std::int64_t>(m.cells.size()) != corners[i + 1] - corners[i])
          throw std::logic_error("VTU: the mesh of subdomain " + std::to_string(m.id) +
                                 " differs from its counted size");
        std::int64_t off = corners[i];
        fill(static_cast<size_t>(i), m, nodes[i], off, b);
        if (narrow) b.narrow();
      };
      if (dfd < 0) {
        // Threads take subdomains and write each array's values to their places.
#pragma omp parallel
        {
          Buffers b;
#pragma omp for schedule(dynamic)
          for (int i = 0; i < ns; ++i) {
            try {
              fill_checked(i, b);
              for (size_t k = 0; k < arrays.size(); ++k) {
                const auto [data, n] = bytes_of(*arrays[k], b);
                put(data, n, start[k] + item[k] * static_cast<std::uint64_t>((*index[k])[i]));
              }
            } catch (const std::exception& e) {
#pragma omp critical
              werr = e.what();
            }
          }
        }
      } else {
        // Each thread takes a contiguous run of subdomains (split by points), so that its values
        // of each array are one contiguous range of the file, appended in subdomain order; one
        // background thread writes the filled stages.
        {
          WriteBehind writer(fd, dfd);
#pragma omp parallel
          {
            const int nt = omp_get_num_threads(), t = omp_get_thread_num();
            auto split = [&](int part) {  // the first subdomain of thread `part`
              return static_cast<int>(
                  std::lower_bound(nodes.begin(), nodes.end() - 1, P * part / nt) - nodes.begin());
            };
            const int lo = split(t), hi = t + 1 == nt ? ns : split(t + 1);
            try {
              std::vector<DirectStream> streams;
              streams.reserve(arrays.size());
              for (size_t k = 0; k < arrays.size(); ++k)
                streams.emplace_back(
                    fd, writer, start[k] + item[k] * static_cast<std::uint64_t>((*index[k])[lo]),
                    start[k] + item[k] * static_cast<std::uint64_t>((*index[k])[hi]));
              Buffers b;
              for (int i = lo; i < hi; ++i) {
                fill_checked(i, b);
                for (size_t k = 0; k < arrays.size(); ++k) {
                  const auto [data, n] = bytes_of(*arrays[k], b);
                  streams[k].append(data, n);
                }
              }
              for (auto& s : streams) s.finish();
            } catch (const std::exception& e) {
#pragma omp critical
              werr = e.what();
            }
          }
        }  // the writer's thread has ended: every stage is on the disk
        ::close(dfd);
      }
      if (::close(fd) != 0 && werr.empty()) werr = "error while closing " + piece;
      if (!werr.empty()) throw std::runtime_error(werr);
    }
    if (comm.size() > 1 && comm.rank() == 0) {
      std::ofstream o(temp_name(files[0]));
      if (!o) throw std::runtime_error("cannot write " + files[0]);
      o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" "
           "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<PUnstructuredGrid "
           "GhostLevel=\"0\">\n<PPointData>\n<PDataArray type=\"Float64\" Name=\"u\""
        << (elastic ? " NumberOfComponents=\"3\"" : "") << "/>\n";
      if (contact)
        o << "<PDataArray type=\"Float64\" Name=\"contact_force\" NumberOfComponents=\"3\"/>\n"
          << "<PDataArray type=\"Float64\" Name=\"contact_gap\"/>\n";
      o << "</PPointData>\n<PCellData>\n<PDataArray type=\"Int32\" Name=\"subdomain\"/>\n"
           "<PDataArray type=\"Int32\" Name=\"cluster\"/>\n<PDataArray type=\"Int32\" "
           "Name=\"rank\"/>\n";
      if (elastic) o << "<PDataArray type=\"Float64\" Name=\"von_mises\"/>\n";
      o << "</PCellData>\n<PPoints><PDataArray type=\"Float64\" "
           "NumberOfComponents=\"3\"/></PPoints>\n";
      for (int r = 0; r < comm.size(); ++r)
        o << "<Piece Source=\"" << std::filesystem::path(files[1 + r]).filename().string()
          << "\"/>\n";
      o << "</PUnstructuredGrid>\n</VTKFile>\n";
      o.flush();
      if (!o) throw std::runtime_error("error while writing " + files[0]);
    }
  } catch (const std::exception& e) {
    error = e.what();
  }
  try {
    comm.agree(error);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(piece_tmp, ec);
    if (comm.rank() == 0 && comm.size() > 1) std::filesystem::remove(temp_name(files[0]), ec);
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(piece_tmp, piece, ec);
  if (!ec && comm.rank() == 0 && comm.size() > 1)
    std::filesystem::rename(temp_name(files[0]), files[0], ec);
  comm.agree(ec ? "cannot rename the output to " + piece + ": " + ec.message() : "");
  written.path = files[0];
  return written;
}

}  // namespace htfeti
