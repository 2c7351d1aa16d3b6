// The per-map tables of the relief ray caster (ReliefRaycaster::Impl): per grey cell its projection data
// in single precision, layer offsets and empty-space bounds, the cell lookup, and the side of the centre of
// every interior grey cell.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <vector>

#include <fmt/format.h>

#include "kernels/core/errors.h"
#include "kernels/relief/raycast_avx2.h"
#include "kernels/relief/raycast_impl.h"

namespace gimforge {
using namespace detail;

namespace {

/// Largest n whose cell lookup is a dense n³ table (16 MiB of int32); a hash of the grey cells above.
constexpr std::uint32_t kMaxDenseGrid = 160;
/// A hit farther than this many texel spacings from the stored surface of its texel lies on a wall (a
/// discontinuity of the stored distances), whose stored normal is that of another surface.
constexpr float kWallTexels = 4.0f;

void check_options(const RaycastOptions& o) {
  if (o.linear_steps < 1 || o.linear_steps > 1024)
    throw InvalidInput(fmt::format("relief ray casting: linear steps {} out of range 1..1024", o.linear_steps));
  if (o.binary_steps > 32)
    throw InvalidInput(fmt::format("relief ray casting: binary steps {} out of range 0..32", o.binary_steps));
  if (!(o.ambient >= 0.0 && o.ambient <= 1.0))
    throw InvalidInput(fmt::format("relief ray casting: ambient {} out of range 0..1", o.ambient));
}

}  // namespace

ReliefRaycaster::Impl::Impl(const ReliefMap& m, const RaycastOptions& o) : map(m), options(o) {
  check_options(o);
  map.check();
  const std::size_t G = map.cells.size();
  const std::uint32_t T = map.texture;
  const std::size_t tpl = map.texels_per_layer();
  cells.resize(G);
  std::vector<std::uint8_t> useful(G, 0);  // the cell's maps hold at least one surface sample
  for (std::size_t g = 0; g < G; ++g) {
    const CellProjection& p = map.projections[g];
    CellData& c = cells[g];
    for (int a = 0; a < 3; ++a) c.point[a] = static_cast<float>(p.point[a]);
    c.type = static_cast<std::uint8_t>(p.type);
    c.axis = p.axis;
    c.side = p.type == ProjectionType::Parallel && p.direction[p.axis] > 0.0 ? 1 : 0;
    c.mode = map.external_faces[g] == 0 ? kInteriorRelative : kBorderCell;
    std::fill(std::begin(c.layer_base), std::end(c.layer_base), kNoLayer);
    std::uint16_t qmin = kEmptyTexel;
    std::uint16_t face_qmin[6];
    std::fill(std::begin(face_qmin), std::end(face_qmin), kEmptyTexel);
    for (std::uint32_t l = map.first_layer[g]; l < map.first_layer[g + 1]; ++l) {
      c.layer_base[map.layer_face[l]] = static_cast<std::uint32_t>(l * tpl);
      const auto* first = map.distances.data() + l * tpl;
      face_qmin[map.layer_face[l]] = *std::min_element(first, first + tpl);
      qmin = std::min(qmin, face_qmin[map.layer_face[l]]);
    }
    useful[g] = qmin != kEmptyTexel ? 1 : 0;
    c.min_dist = c.mode == kBorderCell && useful[g]
                     ? static_cast<float>(dequantize_distance(qmin, map.distance_scale) / map.cell_size)
                     : -1.0f;
    // Farthest cell corner from the centre of projection (axial: in the plane across the axis).
    double reach = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      Vec3 d = Vec3((corner & 1) ? 1.0 : 0.0, (corner & 2) ? 1.0 : 0.0, (corner & 4) ? 1.0 : 0.0) - p.point;
      if (p.type == ProjectionType::Axial) d[p.axis] = 0.0;
      reach = std::max(reach, d.norm());
    }
    c.reach = static_cast<float>(reach * (1.0 + 1e-6));
    set_min_heights(c, p, face_qmin);
    for (int f = 0; f < 6; ++f) c.face_qmin[f] = static_cast<float>(face_qmin[f]);
    if (!options.cull_empty_space) {  // bounds that never cull
      c.min_dist = -1.0f;
      for (int f = 0; f < 6; ++f) {
        c.min_height[f] = 0.0f;
        c.face_qmin[f] = -1.0f;
      }
    }
  }
  const std::uint64_t n = map.n;
  for (std::size_t g = 0; g < G; ++g) {
    if (!useful[g]) continue;
    const std::uint32_t linear = map.cells[g];
    useful_cells.push_back({static_cast<std::int32_t>(g),
                            {static_cast<std::int32_t>(linear % n), static_cast<std::int32_t>(linear / n % n),
                             static_cast<std::int32_t>(linear / (n * n))}});
  }
  dense = map.n <= kMaxDenseGrid;
  if (dense) {
    table.assign(n * n * n, -1);
    for (std::size_t g = 0; g < G; ++g)
      if (useful[g]) table[map.cells[g]] = static_cast<std::int32_t>(g);
  } else {
    const std::size_t count = static_cast<std::size_t>(std::count(useful.begin(), useful.end(), std::uint8_t{1}));
    const std::uint32_t capacity = std::bit_ceil(static_cast<std::uint32_t>(std::max<std::size_t>(2 * count, 16)));
    hash_mask = capacity - 1;
    hash_shift = 32 - std::countr_zero(capacity);
    keys.assign(capacity, HashLookup::kEmptyKey);
    values.assign(capacity, -1);
    const HashLookup h{keys.data(), values.data(), hash_mask, hash_shift};
    for (std::size_t g = 0; g < G; ++g) {
      if (!useful[g]) continue;
      std::uint32_t s = h.slot(map.cells[g]);
      while (keys[s] != HashLookup::kEmptyKey) s = (s + 1) & hash_mask;
      keys[s] = map.cells[g];
      values[s] = static_cast<std::int32_t>(g);
    }
  }
  texels.dist = map.distances.data();
  texels.normals = map.normals.data();
  texels.T = static_cast<std::int32_t>(T);
  texels.tm1 = static_cast<float>(T - 1);
  texels.inv_scale = static_cast<float>(map.cell_size / map.distance_scale);
  inv_cs = 1.0 / map.cell_size;
  wall_tolerance = kWallTexels / static_cast<float>(T - 1);
  steps_per_unit = options.linear_steps * inv_cs;
  min_steps = std::max(1u, (options.linear_steps + 1) / 2);
  resolve_interior_cells();
#if GIMFORGE_RELIEF_AVX2
  // The gathers index the distances with 32-bit signed texel offsets.
  avx2 = o.vectorized && map.distances.size() < (std::size_t{1} << 31) - 2 * std::size_t{T} &&
         __builtin_cpu_supports("avx2");
#endif
}

/// CellData::min_height of border cell c with projection p and per-face smallest quantized distances.
void ReliefRaycaster::Impl::set_min_heights(CellData& c, const CellProjection& p,
                                            const std::uint16_t (&face_qmin)[6]) const {
  for (int f = 0; f < 6; ++f) {
    c.min_height[f] = 0.0f;
    if (c.mode != kBorderCell) continue;
    const int a = f / 2;
    const double plane = (f & 1) ? 1.0 : 0.0;
    if (c.layer_base[f] == kNoLayer || face_qmin[f] == kEmptyTexel ||
        (c.type == static_cast<std::uint8_t>(ProjectionType::Parallel) && f != 2 * c.axis + c.side) ||
        (c.type == static_cast<std::uint8_t>(ProjectionType::Planar) && a != c.axis) ||
        (c.type == static_cast<std::uint8_t>(ProjectionType::Axial) && a == c.axis)) {
      c.min_height[f] = kInfF;  // no sample projects onto f, or f's maps are empty
      continue;
    }
    double k = 1.0;  // parallel, planar: the projected distance is the height
    if (c.type == static_cast<std::uint8_t>(ProjectionType::Perspective) ||
        c.type == static_cast<std::uint8_t>(ProjectionType::Axial)) {
      const double normal = std::abs(plane - p.point[a]);
      if (!(normal > 1e-9)) continue;  // centre on the plane of f: no bound
      const int b = (a + 1) % 3, d = (a + 2) % 3;
      double longest = 0.0;  // over the corners of f: the farthest from the centre (axial: from the axis)
      for (int corner = 0; corner < 4; ++corner) {
        Vec3 q;
        q[a] = plane;
        q[b] = (corner & 1) ? 1.0 : 0.0;
        q[d] = (corner & 2) ? 1.0 : 0.0;
        Vec3 v = q - p.point;
        if (c.type == static_cast<std::uint8_t>(ProjectionType::Axial)) v[p.axis] = 0.0;
        longest = std::max(longest, v.norm());
      }
      k = longest / normal * (1.0 + 1e-6);
    }
    const double m = dequantize_distance(face_qmin[f], map.distance_scale) / map.cell_size;
    c.min_height[f] = static_cast<float>(m / k);
  }
}

/// Side of the unit-cell point p of grey cell g (any projection type; bilinear filter).
Side ReliefRaycaster::Impl::side_of(std::size_t g, const float p[3]) const {
  const CellData& c = cells[g];
  switch (static_cast<ProjectionType>(c.type)) {
    case ProjectionType::Parallel: return point_side<ProjectionType::Parallel, ReliefFilter::Bilinear>(c, texels, p);
    case ProjectionType::Planar: return point_side<ProjectionType::Planar, ReliefFilter::Bilinear>(c, texels, p);
    case ProjectionType::Perspective:
      return point_side<ProjectionType::Perspective, ReliefFilter::Bilinear>(c, texels, p);
    case ProjectionType::Axial: return point_side<ProjectionType::Axial, ReliefFilter::Bilinear>(c, texels, p);
  }
  return Side::Empty;
}

/// Whether the unit-cell point p of grey cell g is inside the object as the cell's maps tell: 1, 0, or
/// −1 when g is an interior cell whose centre is undecided.
int ReliefRaycaster::Impl::inside_at(std::size_t g, const float p[3]) const {
  const Side side = side_of(g, p);
  switch (cells[g].mode) {
    case kBorderCell: return side == Side::Beyond ? 1 : 0;
    case kInteriorOutside: return side == Side::Before ? 1 : 0;
    case kInteriorInside: return side != Side::Before ? 1 : 0;
    default: return -1;
  }
}

/// Decides, for every interior grey cell, whether its centre C (the centre of projection) is inside the
/// object, by votes over a grid of about 16 × 16 texels of each of its six faces: a texel point P' whose
/// status is known (the neighbour across the face is not grey, hence black: inside; or it is a border
/// cell or a decided interior cell, whose maps classify P') votes "C on the same side as P'" when its
/// segment is empty and "C on the other side" when it holds a surface sample. Repeated while cells get
/// decided (an interior cell surrounded by interior cells waits for its neighbours); cells without
/// votes stay kInteriorRelative.
void ReliefRaycaster::Impl::resolve_interior_cells() {
  const std::uint32_t n = map.n, T = map.texture;
  const std::uint32_t stride = std::max<std::uint32_t>(1, (T - 1) / 15);
  auto grey_at = [&](std::uint64_t linear) -> std::int64_t {
    const auto it = std::lower_bound(map.cells.begin(), map.cells.end(), linear);
    return it != map.cells.end() && *it == linear ? it - map.cells.begin() : -1;
  };
  std::vector<std::size_t> pending;
  for (std::size_t g = 0; g < cells.size(); ++g)
    if (cells[g].mode == kInteriorRelative) pending.push_back(g);
  for (int pass = 0; pass < 64 && !pending.empty(); ++pass) {
    std::vector<std::size_t> still;
    for (const std::size_t g : pending) {
      const std::uint64_t linear = map.cells[g];
      const std::uint64_t ijk[3] = {linear % n, linear / n % n, linear / (static_cast<std::uint64_t>(n) * n)};
      std::int64_t votes_in = 0, votes_out = 0;
      for (int f = 0; f < 6; ++f) {
        const int a = f / 2;
        const bool high = (f % 2) != 0;
        std::uint64_t nb[3] = {ijk[0], ijk[1], ijk[2]};
        if (high ? nb[a] + 1 >= n : nb[a] == 0) continue;  // cannot happen for an interior cell
        nb[a] = high ? nb[a] + 1 : nb[a] - 1;
        const std::int64_t h = grey_at((nb[2] * n + nb[1]) * n + nb[0]);
        const std::uint32_t base = cells[g].layer_base[f];
        if (base == kNoLayer) continue;
        for (std::uint32_t j = 0; j < T; j += stride) {
          for (std::uint32_t i = 0; i < T; i += stride) {
            const Vec3 q = face_point(f, map.texel_coord(i), map.texel_coord(j));
            int face_inside = 1;  // black neighbour
            if (h >= 0) {
              float ph[3] = {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2])};
              ph[a] = high ? 0.0f : 1.0f;
              face_inside = inside_at(static_cast<std::size_t>(h), ph);
              if (face_inside < 0) continue;
            }
            const bool empty = map.distances[base + static_cast<std::size_t>(j) * T + i] == kEmptyTexel;
            const bool centre_inside = empty ? face_inside == 1 : face_inside == 0;
            (centre_inside ? votes_in : votes_out) += 1;
          }
        }
      }
      if (votes_in == votes_out)
        still.push_back(g);
      else
        cells[g].mode = votes_in > votes_out ? kInteriorInside : kInteriorOutside;
    }
    if (still.size() == pending.size()) break;
    pending.swap(still);
  }
}


}  // namespace gimforge
