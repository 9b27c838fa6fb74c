// ParaView output of a solution: one VTU file (one rank) or a PVTU file with one VTU piece per
// rank. Binary by default (VTK XML "appended" raw data with 64-bit headers; ASCII on request).
// Fields: the displacement/potential "u" on the points (a 3-vector for elasticity), the contact
// force carried by each copy ("contact_force", B_I^T lambda: summed over a node's copies it is the
// nodal contact force), and per cell the subdomain, cluster and rank ids and, for elasticity, the
// von Mises stress at the cell centroid. Every subdomain writes its own copy of its nodes.
//
// Files are written under temporary names next to the target and renamed only when every rank
// has written its piece without error; on failure nothing is left behind (the error is agreed on
// by all ranks and thrown).
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/model/model.hpp"

namespace htfeti {

/// How the binary pieces reach the file. buffered: positioned writes through the page cache.
/// direct: the whole 4 KiB blocks of the data by direct I/O (O_DIRECT: from the writer's own
/// staging buffers to the disk, no page cache pages to allocate and fill), the partial blocks
/// where two subdomains' values meet through the page cache; a file system that refuses direct
/// I/O gets buffered writes. automatic: direct for pieces of kDirectMinBytes and more.
enum class VtuIo { automatic, buffered, direct };
inline constexpr std::array<EnumName<VtuIo>, 3> kVtuIoNames{
    {{VtuIo::automatic, "auto"}, {VtuIo::buffered, "buffered"}, {VtuIo::direct, "direct"}}};
VtuIo parse_vtu_io(const std::string& name);  // auto | buffered | direct; std::invalid_argument
std::string to_string(VtuIo io);

struct VtuOptions {
  bool ascii = false;
  VtuIo io = VtuIo::automatic;
  static constexpr double kDirectMinBytes = 256.0 * (1 << 20);
};

struct VtuWritten {
  std::string path;  ///< the main file (.vtu or .pvtu)
  std::string io;    ///< how this rank's piece was written: "ascii", "buffered" or "direct"
};

/// The file names that write_vtu would write (the .vtu, or the .pvtu and its pieces).
std::vector<std::string> vtu_files(const std::string& path, int ranks);

/// Writes the solution; returns the path of the main file (.vtu or .pvtu). Collective.
VtuWritten write_vtu(const std::string& path, const Model& model, DualProblem& dual,
                     const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda,
                     const VtuOptions& options = {});

/// The XDMF output: FILE.xdmf (or .xmf), light XML that ParaView opens, and beside it FILE.h5,
/// one HDF5 file written by all ranks at once (MPI-IO through parallel HDF5): the same points,
/// cells and arrays as the VTU, each a dataset of the whole mesh (/points, /cells with global
/// point ids, /u, ..., /subdomain, /von_mises), rank r's values after those of ranks < r.
/// Returns {xdmf, h5} for a given path.
std::vector<std::string> xdmf_files(const std::string& path);

/// Writes the XDMF output (collective); as write_vtu, nothing is left behind on failure.
void write_xdmf(const std::string& path, const Model& model, DualProblem& dual,
                const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& lambda);

}  // namespace htfeti
