#pragma once
// The band along the edges of a domain.  The boundary condition P = 0 holds
// there only if the domain is large enough; pressure in the band shows that
// it takes load away (the rolling contact's inlet and sides: RollingProblem;
// the squeeze film of the impact's approach: ImpactProblem, RunGuards).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "grid/Grid.hpp"

namespace ehlsim {

/// Points within this share of the domain's side from an edge make its edge band.
inline constexpr double kEdgeBand = 0.1;

/// The edges of the domain that a band runs along (all four by default).
struct DomainEdges {
  bool x_min = true, x_max = true, y_min = true, y_max = true;
};

/// The weight of a point `points_from_edge` meshes from the nearest edge of a
/// band `band_meshes` wide: 1 inside, the fraction of the mesh the band covers
/// for the first point beyond a whole number of meshes, 0 outside.  So the
/// band covers the same area on every grid.
[[nodiscard]] inline double edge_band_weight(int points_from_edge, double band_meshes) {
  return std::clamp(band_meshes + 1.0 - points_from_edge, 0.0, 1.0);
}

/// The weighted sum of P over the interior points of the full grid that
/// `grid` stands for (counted as full_interior_sum counts them) within
/// kEdgeBand of the side from one of `edges` (edge_band_weight).  A mirrored
/// grid stands for a domain whose band runs along all four edges: other
/// `edges` throw std::invalid_argument.
[[nodiscard]] inline double edge_band_sum(const Grid2D& grid, const Field& P,
                                          DomainEdges edges = {}) {
  const bool all_edges = edges.x_min && edges.x_max && edges.y_min && edges.y_max;
  if (grid.mirrored && !all_edges)
    throw std::invalid_argument("edge_band_sum: the band of a mirrored grid runs along every edge");
  const int last = grid.n - 1;
  const double band_meshes = kEdgeBand * (grid.full().n - 1);
  constexpr int kNoEdge = std::numeric_limits<int>::max();
  // Points from the nearest edge of the band along one axis; on a mirrored
  // grid the point k stands for -k and k, last - k points from either edge.
  const auto from_edge = [&](int k, bool low, bool high) {
    if (grid.mirrored) return last - k;
    return std::min(low ? k : kNoEdge, high ? last - k : kNoEdge);
  };
  return full_interior_sum(grid, [&](int i, int j) {
    const int points_from_edge =
        std::min(from_edge(i, edges.x_min, edges.x_max), from_edge(j, edges.y_min, edges.y_max));
    return edge_band_weight(points_from_edge, band_meshes) * P(i, j);
  });
}

}  // namespace ehlsim
