#include "htfeti/io/vtu.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace htfeti {

namespace {

std::string stem_of(const std::string& path) {
  const auto p = std::filesystem::path(path);
  if (p.extension() == ".vtu" || p.extension() == ".pvtu")
    return (p.parent_path() / p.stem()).string();
  return path;
}

void write_piece(const std::string& file, const DualProblem& dual,
                 const std::vector<Eigen::VectorXd>& u) {
  const Decomposition& dec = dual.decomposition();
  const int H = dec.H(), np = H + 1;
  const bool tri = dec.options().element == ElementKind::p1;
  const auto& subs = dual.subdomains();
  const long points = static_cast<long>(subs.size()) * np * np;
  const long cells = static_cast<long>(subs.size()) * H * H * (tri ? 2 : 1);
  const std::string tmp = file + ".tmp";
  {
    std::ofstream o(tmp);
    if (!o) throw std::runtime_error("cannot write " + file);
    o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\">\n"
      << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << points << "\" NumberOfCells=\"" << cells
      << "\">\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    o.precision(10);
    for (const auto& s : subs)
      for (int k = 0; k < np * np; ++k) o << s->x_of(k) << ' ' << s->y_of(k) << " 0\n";
    o << "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" "
         "format=\"ascii\">\n";
    for (size_t si = 0; si < subs.size(); ++si) {
      const long base = static_cast<long>(si) * np * np;
      for (int b = 0; b < H; ++b)
        for (int a = 0; a < H; ++a) {
          const long n0 = base + b * np + a, n1 = n0 + 1, n2 = n0 + np + 1, n3 = n0 + np;
          if (tri)
            o << n0 << ' ' << n1 << ' ' << n2 << '\n' << n0 << ' ' << n2 << ' ' << n3 << '\n';
          else
            o << n0 << ' ' << n1 << ' ' << n2 << ' ' << n3 << '\n';
        }
    }
    o << "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    for (long c = 1; c <= cells; ++c) o << c * (tri ? 3 : 4) << '\n';
    o << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (long c = 0; c < cells; ++c) o << (tri ? 5 : 9) << '\n';
    o << "</DataArray>\n</Cells>\n<PointData Scalars=\"u\">\n"
      << "<DataArray type=\"Float64\" Name=\"u\" format=\"ascii\">\n";
    o.precision(12);
    for (const auto& v : u)
      for (int k = 0; k < v.size(); ++k) o << v[k] << '\n';
    o << "</DataArray>\n</PointData>\n<CellData>\n";
    const int per_sub = H * H * (tri ? 2 : 1);
    for (const char* name : {"subdomain", "cluster", "rank"}) {
      o << "<DataArray type=\"Int32\" Name=\"" << name << "\" format=\"ascii\">\n";
      for (const auto& s : subs) {
        const int v = name[0] == 's'   ? s->id()
                      : name[0] == 'c' ? dec.cluster_of(s->id())
                                       : dual.comm().rank();
        for (int c = 0; c < per_sub; ++c) o << v << '\n';
      }
      o << "</DataArray>\n";
    }
    o << "</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    if (!o) throw std::runtime_error("error while writing " + file);
  }
  std::filesystem::rename(tmp, file);
}

}  // namespace

std::string write_vtu(const std::string& path, const DualProblem& dual,
                      const std::vector<Eigen::VectorXd>& u) {
  const Comm& comm = dual.comm();
  const std::string stem = stem_of(path);
  if (comm.size() == 1) {
    write_piece(stem + ".vtu", dual, u);
    return stem + ".vtu";
  }
  const std::string piece = stem + "_" + std::to_string(comm.rank()) + ".vtu";
  write_piece(piece, dual, u);
  comm.barrier();
  const std::string master = stem + ".pvtu";
  if (comm.rank() == 0) {
    const std::string tmp = master + ".tmp";
    {
      std::ofstream o(tmp);
      if (!o) throw std::runtime_error("cannot write " + master);
      o << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"0.1\">\n"
        << "<PUnstructuredGrid GhostLevel=\"0\">\n<PPoints><PDataArray type=\"Float64\" "
           "NumberOfComponents=\"3\"/></PPoints>\n<PPointData Scalars=\"u\"><PDataArray "
           "type=\"Float64\" Name=\"u\"/></PPointData>\n<PCellData>"
        << "<PDataArray type=\"Int32\" Name=\"subdomain\"/><PDataArray type=\"Int32\" "
           "Name=\"cluster\"/><PDataArray type=\"Int32\" Name=\"rank\"/></PCellData>\n";
      const std::string base = std::filesystem::path(stem).filename().string();
      for (int r = 0; r < comm.size(); ++r)
        o << "<Piece Source=\"" << base << "_" << r << ".vtu\"/>\n";
      o << "</PUnstructuredGrid>\n</VTKFile>\n";
    }
    std::filesystem::rename(tmp, master);
  }
  comm.barrier();
  return master;
}

}  // namespace htfeti
