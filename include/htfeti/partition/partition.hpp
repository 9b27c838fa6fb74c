// Decomposition of a whole mesh (DESIGN.md, partition/): subdomains by METIS k-way partitioning
// of the cell dual graph (cells adjacent through a shared edge in 2D, a shared face in 3D),
// clusters by METIS k-way partitioning of the subdomain adjacency graph (subdomains adjacent
// when they share a node, weighted by the number of shared nodes). A mesh of several bodies
// (connected components that share no node: parts meshed apart, in contact) is split body by
// body, each into a share of the subdomains proportional to its cells, and its clusters are
// formed within each body: no subdomain or cluster spans two bodies. Subdomains are then numbered
// cluster-major (the subdomains of a cluster are contiguous), and each node lists the
// subdomains holding a copy in increasing id order. METIS runs with a fixed seed, so every rank
// computes the same partition.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "htfeti/enum_names.hpp"
#include "htfeti/mesh/mesh.hpp"
#include "htfeti/mesh/subdomain_mesh.hpp"

namespace htfeti {

/// What METIS minimizes when it splits the cells into subdomains:
/// - volume: the total communication volume (METIS_OBJTYPE_VOL: roughly the interface nodes
///   counted once per extra subdomain holding them). On the METIS-split cube-obstacle it halves
///   the Hessian products against the cut (docs/performance.md, bench/metis_partition.py).
/// - cut: the edge cut of the dual graph (METIS_OBJTYPE_CUT: the number of cut facets).
/// - area: the edge cut of the dual graph weighted by each facet's area (length in 2D): the
///   interfaces run across the small faces of stretched cells. On a graded structured hex mesh
///   it cuts PCG's iterations by three and the contact products by two (bench/graded_hertz.py).
/// - automatic: area when at least kStretchedShare of the cells are stretched (their largest
///   facet at least kStretchRatio times their smallest), else volume. The partition says which.
enum class PartitionObjective { volume, cut, area, automatic };
inline constexpr std::array<EnumName<PartitionObjective>, 4> kPartitionObjectiveNames{
    {{PartitionObjective::volume, "volume"},
     {PartitionObjective::cut, "cut"},
     {PartitionObjective::area, "area"},
     {PartitionObjective::automatic, "auto"}}};
inline constexpr double kStretchRatio = 2.5, kStretchedShare = 0.1;
PartitionObjective parse_partition_objective(const std::string& name);  // std::invalid_argument
std::string to_string(PartitionObjective objective);

/// How a METIS split of a mesh forms H-TFETI-DP's clusters (cluster_size > 1):
/// - mesh: METIS splits each body into ceil(subdomains of the body / cluster_size) clusters, then
///   each cluster into its share of the body's subdomains (proportional to its cells). Clusters
///   are compact pieces of the mesh, and the subdomains of a cluster share many faces, as a
///   cluster of a box split does. The default.
/// - subdomains: METIS splits the mesh into the subdomains (the same as with cluster_size = 1),
///   which METIS then groups by their adjacency (cluster_subdomains). The clusters follow the
///   subdomains' shapes: on a cube of 64 parts in clusters of 8 their face-average graphs were
///   nearly trees, with necks of a few nodes, and F was so ill-conditioned that PCG took 461
///   iterations to 1e-10 where TFETI on the same parts took 48 and the mesh split 63
///   (docs/method.md, "Clusters of a METIS split"). Kept for comparing H-TFETI-DP and TFETI on
///   the same subdomains.
enum class ClusterSplit { mesh, subdomains };
inline constexpr std::array<EnumName<ClusterSplit>, 2> kClusterSplitNames{
    {{ClusterSplit::mesh, "mesh"}, {ClusterSplit::subdomains, "subdomains"}}};
ClusterSplit parse_cluster_split(const std::string& name);  // std::invalid_argument
std::string to_string(ClusterSplit split);

/// The shape of the parts of a METIS split (decomposition.shape):
/// - compact: METIS's split, then moved toward compact parts of equal cell counts (a centroidal
///   power diagram of the cells' centroids, Lloyd's iteration: the balanced k-means of geometric
///   partitioners), kept where the parts stay whole and the cut facets fall to kCompactGain of
///   METIS's or fewer. METIS's parts on a structured mesh include tongues and thin parts, whose
///   soft modes set ‖PFP‖ and the products of a contact solve; on the 80^3 cube-obstacle in 512
///   parts the compact split takes 41 products against METIS's 94 and the box split's 35
///   (docs/performance.md, "Compact parts"). Where the cells' sizes vary strongly (graded
///   meshes) the cut does not fall and METIS's split stays. The default.
/// - metis: METIS's split as it is.
enum class PartitionShape { compact, metis };
inline constexpr std::array<EnumName<PartitionShape>, 2> kPartitionShapeNames{
    {{PartitionShape::compact, "compact"}, {PartitionShape::metis, "metis"}}};
PartitionShape parse_partition_shape(const std::string& name);  // std::invalid_argument
std::string to_string(PartitionShape shape);
/// compact_split's parameters (partition.cpp): the largest count over the mean, the weight step,
/// the rounds of Lloyd's iteration, the sweeps per round, the share of moved cells below which
/// it has settled, and the cut facets (to METIS's) at or below which the compact split is kept.
inline constexpr double kCompactImbalance = 1.03, kCompactStep = 0.5, kCompactSettled = 1e-3,
                        kCompactGain = 0.98;
inline constexpr int kCompactRounds = 30, kCompactBalanceSweeps = 10;

/// METIS's random seed unless one is given (decomposition.seed). METIS's splits of a mesh differ
/// from seed to seed, and so do the iterations of a FETI solve on them: on the cube-obstacle
/// 40^3 in 64 parts at A = 20 the products range over 59-103 for seeds 1-8 on METIS's own parts
/// (docs/performance.md, "METIS's seed"), 34-42 for seeds 1-4 on the compact parts made from them.
inline constexpr int kDefaultPartitionSeed = 1;

struct MeshPartition {
  int num_bodies = 1;          ///< connected components of the cells (numbered by first cell)
  std::vector<int> cell_body;  ///< per cell
  int num_subdomains = 0;
  int num_clusters = 0;
  std::vector<int> cluster_first;   ///< num_clusters + 1
  std::vector<int> cell_subdomain;  ///< per cell
  std::vector<std::vector<int>> subdomain_cells;
  std::vector<int> copy_offset, copy_list;            ///< per global node: subdomains holding it
  std::vector<char> on_boundary;                      ///< per global node
  std::vector<int> node_cell_offset, node_cell_list;  ///< per global node: its cells
  PartitionObjective objective = PartitionObjective::volume;  ///< as used (automatic resolved)
  double stretched_share = 0;  ///< share of stretched cells (computed for automatic only)
  ClusterSplit cluster_split = ClusterSplit::mesh;  ///< how the clusters were formed
  /// METIS splits whose parts were in pieces or hinged: cells moved to a neighbouring part to
  /// repair them (repair_parts), and splits redone by METIS with connected parts asked for.
  long repaired_cells = 0;
  int contiguous_splits = 0;
  /// Coefficient jumps (partition_mesh's cell_coefficient): the regions between jumps that were
  /// split apart (each into its own subdomains; 0 when none was: no coefficient field, no jump,
  /// or jump_ratio 0), and the bodies or clusters whose subdomains were too few for their regions
  /// and were split as a whole (their subdomains may straddle a jump).
  int jump_regions = 0;
  int jump_splits_declined = 0;
  /// PartitionShape::compact: the splits (of a body, cluster or region) made compact, and those
  /// that kept METIS's parts (unbalanced, in pieces, or no fewer cut facets).
  int compact_splits = 0;
  int compact_declined = 0;
  /// Wall seconds of the split (set by the model that made it; the report's timings.partition).
  double seconds = 0;
  /// The mesh's groups by subdomain, for extract_subdomain (built once by partition_mesh, so that
  /// extracting a subdomain costs its own size, not the groups' sizes): per subdomain and group
  /// (in the mesh's name order; groups the subdomain does not touch left out), the global node
  /// ids and cell ids in the group's order, and the facets (index of the facet in the group) the
  /// subdomain owns: a boundary facet belongs to the lowest subdomain with a cell holding it.
  struct Groups {
    std::vector<std::pair<std::string, std::vector<int>>> nodes, cells, facets;
  };
  std::vector<Groups> groups;  ///< per subdomain
};

/// A split whose parts are in pieces or hinged at a node or an edge, repaired by moving pieces:
/// in every part the cells joined through facets form pieces, and all but the largest move to
/// the part they share the most facets with. Returns the cells moved, or -1 (part unchanged)
/// when a piece touches no other part through a facet, a part would grow beyond twice the mean,
/// or more than max_share of the cells would move. partition_mesh repairs METIS's split this
/// way when at most kRepairShare of the cells move, and otherwise asks METIS again for connected
/// parts.
constexpr double kRepairShare = 0.01;
long repair_parts(const Mesh& mesh, std::vector<int>& part, double max_share);

/// The share of the cells whose largest facet measure (area in 3D, length in 2D) is at least
/// kStretchRatio times their smallest: elongated or flat cells (a graded structured mesh).
double stretched_cell_share(const Mesh& mesh);

/// Throws std::invalid_argument if the numbers do not fit the mesh (an empty subdomain).
/// cluster_size: subdomains per cluster (1: TFETI); split: how clusters are formed.
/// seed: METIS's random seed (METIS_OPTION_SEED) for every METIS call of the split (subdomains,
/// clusters).
/// cell_coefficient (optional, one positive value per cell: the coefficient field at the cells'
/// centroids) and jump_ratio > 1: a jump is a facet whose two cells' coefficients differ by more
/// than jump_ratio times; the cells of every body (or cluster split from the mesh) fall into
/// regions, connected through facets without a jump, and each region is split into its own
/// subdomains, in number proportional to its cells (at least one each): no subdomain straddles
/// a jump, the case in which FETI's preconditioners with stiffness scaling stay robust (Klawonn
/// and Widlund 2001). Where a body or cluster has more regions than subdomains, it is split as
/// a whole (counted in jump_splits_declined), and so is one where a region's subdomains would
/// average more than kJumpImbalance times the mean subdomain (many small regions: an inclusion
/// of a few cells each would leave the rest of the mesh too few subdomains).
/// shape: compact parts or METIS's as they are (PartitionShape); each split (body, cluster,
/// region between jumps) is made compact on its own.
MeshPartition partition_mesh(const Mesh& mesh, int subdomains, int cluster_size,
                             PartitionObjective objective = PartitionObjective::automatic,
                             ClusterSplit split = ClusterSplit::mesh,
                             int seed = kDefaultPartitionSeed,
                             const std::vector<double>* cell_coefficient = nullptr,
                             double jump_ratio = 0, PartitionShape shape = PartitionShape::compact);
/// The default jump_ratio of a METIS split (decomposition.jump_ratio).
inline constexpr double kDefaultJumpRatio = 10, kJumpImbalance = 2;

/// Clusters of subdomains (H-TFETI-DP): METIS k-way on the subdomain graph of each body apart
/// (subdomains [body_first[b], body_first[b + 1]) form body b; adjacency[s] maps each neighbour
/// of s to the weight of their edge, the nodes they share), ceil(subdomains of the body /
/// cluster_size) clusters per body, with METIS's seed `seed`. Returns the cluster of each
/// subdomain (some clusters may be empty); adjacency is not read when cluster_size is 1.
std::vector<int> cluster_subdomains(const std::vector<std::map<int, int>>& adjacency,
                                    const std::vector<int>& body_first, int cluster_size,
                                    int seed = kDefaultPartitionSeed);

/// Subdomains renumbered cluster-major: empty clusters dropped, new_id[s] the new id of
/// subdomain s (the subdomains of a cluster keep their order), cluster_first the first new id of
/// each cluster (num_clusters + 1 entries).
struct ClusterOrder {
  std::vector<int> new_id, cluster_first;
};
ClusterOrder order_by_cluster(const std::vector<int>& cluster);

/// The SubdomainMesh of subdomain s (local nodes in global order, groups restricted to it).
SubdomainMesh extract_subdomain(const Mesh& mesh, const MeshPartition& part, int s);

}  // namespace htfeti
