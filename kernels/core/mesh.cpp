#include "kernels/core/mesh.h"

namespace gimforge {

BoundingBox bounding_box(MeshView mesh) {
  BoundingBox box;
  if (mesh.faces.empty()) {
    for (const Vec3& p : mesh.positions) box.extend(p);
    return box;
  }
  std::vector<char> seen(mesh.positions.size(), 0);
  for (const Face& f : mesh.faces) {
    for (std::uint32_t v : f) {
      if (v < seen.size() && !seen[v]) {
        seen[v] = 1;
        box.extend(mesh.positions[v]);
      }
    }
  }
  return box;
}

double triangle_area(MeshView mesh, std::size_t f) {
  const Face& t = mesh.faces[f];
  const Vec3& a = mesh.positions[t[0]];
  return 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
}

double surface_area(MeshView mesh) {
  double sum = 0.0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) sum += triangle_area(mesh, f);
  return sum;
}

void translate(TriMesh& mesh, const Vec3& offset) {
  for (Vec3& p : mesh.positions) p += offset;
}

}  // namespace gimforge
