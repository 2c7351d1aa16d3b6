#pragma once
/// \file grid_quad.h
/// The one test of a sound quad of an adaptive sample grid, shared by every step that moves samples (strips,
/// ROI enhancement, the §3.3 moves): its corners, counter-clockwise in the parameter square, turn left at
/// every corner by more than kMinTurnSine (the sine of the turn, about half a degree: a corner nearly straight
/// makes a sliver whose reconstruction triangles stand on edge), no side is shorter than `shortest`, and the
/// test holds for the corners rounded to float32, as the archive stores them (`sample_uv`; readers refuse a
/// quad that is not strictly convex there).
#include <array>
#include <cmath>

#include "kernels/param/stretch.h"

namespace gimforge {

inline constexpr double kMinTurnSine = 1e-2;

/// Whether quad q (counter-clockwise corners) is sound: see the file comment.
[[nodiscard]] inline bool sound_quad(const std::array<Vec2, 4>& q, double shortest) {
  std::array<Vec2, 4> r;
  for (std::size_t k = 0; k < 4; ++k) r[k] = Vec2(static_cast<float>(q[k].x()), static_cast<float>(q[k].y()));
  for (std::size_t e = 0; e < 4; ++e) {
    const Vec2 a = r[(e + 1) % 4] - r[e], b = r[(e + 2) % 4] - r[(e + 1) % 4];
    const double la = a.norm(), lb = b.norm();
    if (!(la >= shortest) || !(lb > 0.0)) return false;
    if (!(a.x() * b.y() - a.y() * b.x() > kMinTurnSine * la * lb)) return false;
  }
  return true;
}

}  // namespace gimforge
