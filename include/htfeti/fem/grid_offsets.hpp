// Points of a generated grid as offsets in whole grid spacings: the same bits at every position of
// the box, where the coordinates g h round differently from place to place. Used for the element
// matrices, kernels and fixed dofs of a subdomain (fem/physics.cpp) and for the kernel of an
// averaged face or edge (the frame the model hands to feti/constraints.cpp through
// DofSharing::kernel_frame), so that equal subdomains of a box are equal bit
// for bit and can share their matrix, factor and cluster solves.
#pragma once

#include <cmath>

namespace htfeti {

/// out[3a + d] = round((xyz[3a + d] - origin[d]) / h_d) h_d for the n points (0 where h_d = 0).
/// out may be xyz; origin must not point into out.
inline void grid_offsets(const double spacing[3], const double* xyz, double* out, int n,
                         const double origin[3]) {
  for (int a = 0; a < n; ++a)
    for (int d = 0; d < 3; ++d) {
      const double h = spacing[d];
      out[3 * a + d] = h > 0 ? std::nearbyint((xyz[3 * a + d] - origin[d]) / h) * h : 0.0;
    }
}

}  // namespace htfeti
