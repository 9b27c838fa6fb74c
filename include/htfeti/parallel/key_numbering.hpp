// Rank-count-independent global numbering of items identified by sortable keys, without any
// rank enumerating all of them (DESIGN.md, "Parallel rules").
//
// Every rank passes the keys it touches (an item may be touched by several ranks). The global
// index of a key is its position in the sorted set of all distinct keys. Keys are sent to
// "bucket" ranks by a monotone map of their leading position (bucket(t) = t * P / T), each bucket
// sorts and counts its distinct keys, an exclusive scan gives the buckets' offsets, and the
// indices go back to the ranks that asked. Communication: two all-to-all exchanges of the
// touched keys (64-bit counts are not needed below 2^31 / 6 keys per pair of ranks; checked).
#pragma once

#include <array>
#include <functional>
#include <vector>

#include "htfeti/parallel/comm.hpp"

namespace htfeti {

using NumberingKey = std::array<long long, 6>;

/// keys: touched keys (any order, may repeat); position(key) in [0, positions) orders the
/// buckets and must be monotone in the key order. Returns the global index of each key and sets
/// `total` to the number of distinct keys. Collective.
std::vector<long long> number_keys(const Comm& comm, const std::vector<NumberingKey>& keys,
                                   long long positions,
                                   const std::function<long long(const NumberingKey&)>& position,
                                   long long& total);

}  // namespace htfeti
