#include "htfeti/io/vtu.hpp"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "htfeti/fem/element.hpp"

namespace htfeti {

namespace {

std::string stem_of(const std::string& path) {
  const auto p = std::filesystem::path(path);
  if (p.extension() == ".vtu" || p.extension() == ".pvtu")
    return (p.parent_path() / p.stem()).string();
  return path;
}

std::string temp_name(const std::string& file) {
  return file + ".htfeti-tmp-" + std::to_string(::getpid());
}

// One data array: name, VTK type, components, raw bytes.
struct Array {
  std::string name, type;
  int components = 1;
  std::string bytes;
};

template <class T>
Array make_array(const std::string& name, const std::string& type, int comps,
                 const std::vector<T>& v) {
  Array a{name, type, comps, std::string()};
  a.bytes.assign(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  return a;
}

template <class T>
void write_ascii_values(std::ostream& o, const std::string& bytes) {
  const T* v = reinterpret_cast<const T*>(bytes.data());
  const size_t n = bytes.size() / sizeof(T);
  o.precision(17);
  for (size_t i = 0; i < n; ++i) o << +v[i] << (i + 1 == n ? "\n" : " ");
}

void write_piece_file(const std::string& file, long points, long cells,
                      const std::vector<Array>& point_arrays, const Array& coords,
                      const std::vector<Array>& cell_struct, const std::vector<Array>& cell_arrays,
                      bool ascii) {
  std::ofstream o(file, std::ios::binary);
  if (!o) throw std::runtime_error("cannot write " + file);
  o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
       "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n<Piece "
       "NumberOfPoints=\""
    << points << "\" NumberOfCells=\"" << cells << "\">\n";
  std::uint64_t offset = 0;
  std::vector<const Array*> order;
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
      offset += sizeof(std::uint64_t) + a.bytes.size();
      order.push_back(&a);
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
  if (!ascii) {
    o << "<AppendedData encoding=\"raw\">\n_";
    for (const Array* a : order) {
      const std::uint64_t n = a->bytes.size();
      o.write(reinterpret_cast<const char*>(&n), sizeof(n));
      o.write(a->bytes.data(), static_cast<std::streamsize>(a->bytes.size()));
    }
    o << "\n</AppendedData>\n";
  }
  o << "</VTKFile>\n";
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

std::string write_vtu(const std::string& path, const Model& model, DualProblem& dual,
                      const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda,
                      const VtuOptions& options) {
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
    std::vector<double> xyz, uu, cf, cg, vm;
    std::vector<std::int64_t> conn, offs;
    std::vector<std::uint8_t> types;
    std::vector<std::int32_t> sub_id, clu_id, rank_id;
    const auto& subs = dual.subdomains();
    std::int64_t base = 0, off = 0;
    for (size_t i = 0; i < subs.size(); ++i) {
      const SubdomainMesh m = model.mesh(subs[i]->id());
      const int nn = m.num_nodes(), nc = cell_nodes(m.type), ne = m.num_cells();
      xyz.insert(xyz.end(), m.coords.begin(), m.coords.end());
      for (int k = 0; k < nn; ++k) {
        if (!elastic) {
          uu.push_back(u[i][k]);
        } else {
          for (int d = 0; d < 3; ++d) uu.push_back(d < dpn ? u[i][k * dpn + d] : 0.0);
        }
        if (contact) {
          for (int d = 0; d < 3; ++d) cf.push_back(d < dpn ? forces[i][k * dpn + d] : 0.0);
          cg.push_back(gaps[i][k]);
        }
      }
      const Eigen::MatrixXd D = elastic ? elasticity_matrix(m.dim, ph.material) : Eigen::MatrixXd();
      for (int e = 0; e < ne; ++e) {
        const int* cn = m.cells.data() + static_cast<size_t>(e) * nc;
        for (int a = 0; a < nc; ++a) conn.push_back(base + cn[a]);
        off += nc;
        offs.push_back(off);
        types.push_back(static_cast<std::uint8_t>(vtk_cell_type(m.type)));
        sub_id.push_back(m.id);
        clu_id.push_back(m.cluster);
        rank_id.push_back(comm.rank());
        if (elastic) {
          double x[24];
          Eigen::VectorXd ue(nc * dpn);
          for (int a = 0; a < nc; ++a) {
            for (int d = 0; d < 3; ++d) x[3 * a + d] = m.coords[3 * static_cast<size_t>(cn[a]) + d];
            for (int d = 0; d < dpn; ++d) ue[a * dpn + d] = u[i][cn[a] * dpn + d];
          }
          const Eigen::VectorXd stress = D * (strain_matrix_at_centroid(m.type, x) * ue);
          vm.push_back(von_mises(m.dim, stress, ph.material.poisson));
        }
      }
      base += nn;
    }
    std::vector<Array> pa{make_array("u", "Float64", elastic ? 3 : 1, uu)};
    if (contact) {
      pa.push_back(make_array("contact_force", "Float64", 3, cf));
      pa.push_back(make_array("contact_gap", "Float64", 1, cg));
    }
    std::vector<Array> ca{make_array("subdomain", "Int32", 1, sub_id),
                          make_array("cluster", "Int32", 1, clu_id),
                          make_array("rank", "Int32", 1, rank_id)};
    if (elastic) ca.push_back(make_array("von_mises", "Float64", 1, vm));
    write_piece_file(piece_tmp, static_cast<long>(base), static_cast<long>(types.size()), pa,
                     make_array("Points", "Float64", 3, xyz),
                     {make_array("connectivity", "Int64", 1, conn),
                      make_array("offsets", "Int64", 1, offs), make_array("types", "UInt8", 1, types)},
                     ca, options.ascii);
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
  return files[0];
}

}  // namespace htfeti
