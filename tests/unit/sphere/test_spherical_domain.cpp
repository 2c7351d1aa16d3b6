// Spherical domains, their unfoldings into images and the boundary extension rules (Praun & Hoppe 2003,
// §4.1, §4.2), and watertight reconstruction with level of detail (§6).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/sphere/spherical_domain.h"
#include "kernels/core/topology.h"

namespace gimforge {
namespace {

using Edge = std::pair<std::uint32_t, std::uint32_t>;

Edge make_edge(std::uint32_t a, std::uint32_t b) { return {std::min(a, b), std::max(a, b)}; }

/// Edges of a mesh as unordered vertex pairs.
std::set<Edge> edge_set(const TriMesh& mesh) {
  std::set<Edge> edges;
  for (const Face& f : mesh.faces)
    for (std::size_t k = 0; k < 3; ++k) edges.insert(make_edge(f[k], f[(k + 1) % 3]));
  return edges;
}

/// Graph distance of every vertex from the vertices in `sources` (breadth-first over `edges`).
std::vector<int> graph_distance(std::size_t num_vertices, const std::set<Edge>& edges,
                                const std::vector<std::uint32_t>& sources) {
  std::vector<std::vector<std::uint32_t>> adjacent(num_vertices);
  for (const auto& [a, b] : edges) {
    adjacent[a].push_back(b);
    adjacent[b].push_back(a);
  }
  std::vector<int> dist(num_vertices, -1);
  std::deque<std::uint32_t> queue;
  for (std::uint32_t s : sources)
    if (dist[s] < 0) {
      dist[s] = 0;
      queue.push_back(s);
    }
  while (!queue.empty()) {
    const std::uint32_t v = queue.front();
    queue.pop_front();
    for (std::uint32_t w : adjacent[v])
      if (dist[w] < 0) {
        dist[w] = dist[v] + 1;
        queue.push_back(w);
      }
  }
  return dist;
}

/// Expected image sizes and sample counts of §4.1, Fig. 6.
struct Expected {
  std::int32_t width, height, faces;
  std::size_t domain_points, triangles;
};

Expected expected_layout(SphericalDomain d, std::int32_t n) {
  const auto nn = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
  switch (d) {
    case SphericalDomain::Tetrahedron: return {2 * n, n + 1, 1, 2 * nn + 2, 4 * nn};
    case SphericalDomain::Cube: return {n + 1, n + 1, 6, 6 * nn + 2, 12 * nn};
    default: return {2 * n + 1, 2 * n + 1, 1, 4 * nn + 2, 8 * nn};
  }
}

/// True when p lies on the surface of the domain polyhedron D (tolerance 1e-12).
bool on_domain(SphericalDomain d, const Vec3& p) {
  constexpr double eps = 1e-12;
  switch (d) {
    case SphericalDomain::Octahedron: return std::abs(p.lpNorm<1>() - 1.0) < eps;
    case SphericalDomain::Cube: return std::abs(p.lpNorm<Eigen::Infinity>() - 1.0) < eps;
    case SphericalDomain::FlatOctahedron: return p.z() == 0.0 && p.lpNorm<1>() <= 1.0 + eps;
    case SphericalDomain::Tetrahedron: {
      // The face opposite vertex v lies in the plane −v·p = 1; p is on D when the largest of these is 1.
      const double face_support = std::max({-p.x() - p.y() - p.z(), -p.x() + p.y() + p.z(), p.x() - p.y() + p.z(),
                                            p.x() + p.y() - p.z()});
      return std::abs(face_support - 1.0) < eps;
    }
  }
  return false;
}

/// One image edge of a face: its stored samples and the outward step across it.
struct ImageEdge {
  std::vector<SampleIndex> samples;
  std::int32_t di, dj;
};

std::vector<ImageEdge> image_edges(const DomainImage& image, std::int32_t face) {
  const std::int32_t w = image.width();
  const std::int32_t h = image.height();
  // The tetrahedron's left/right edges are the periodic wrap; its rightmost column is not stored, so
  // its "right edge" is the virtual column w (= column 0).
  const std::int32_t last_col = image.domain() == SphericalDomain::Tetrahedron ? w : w - 1;
  std::vector<ImageEdge> edges{{{}, 0, -1}, {{}, 0, 1}, {{}, -1, 0}, {{}, 1, 0}};
  for (std::int32_t i = 0; i <= last_col; ++i) {
    edges[0].samples.push_back({face, i, 0});
    edges[1].samples.push_back({face, i, h - 1});
  }
  for (std::int32_t j = 0; j < h; ++j) {
    edges[2].samples.push_back({face, 0, j});
    edges[3].samples.push_back({face, last_col, j});
  }
  return edges;
}

class SphericalDomainTest : public ::testing::TestWithParam<std::tuple<SphericalDomain, std::uint32_t>> {
 protected:
  SphericalDomainTest()
      : image_(std::get<0>(GetParam()), std::get<1>(GetParam())), ids_(image_.vertex_ids()),
        mesh_(reconstruct_spherical_image(image_, domain_positions(image_, DomainEmbedding::Sphere))),
        edges_(edge_set(mesh_)) {}

  [[nodiscard]] std::uint32_t id(const SampleIndex& s) const { return ids_[image_.linear_index(s)]; }
  [[nodiscard]] std::uint32_t id_at(std::int32_t f, std::int32_t i, std::int32_t j) const {
    return id(image_.resolve(f, i, j));
  }
  [[nodiscard]] bool cube_corner_region(std::int32_t i, std::int32_t j) const {
    const bool i_out = i < 0 || i >= image_.width();
    const bool j_out = j < 0 || j >= image_.height();
    return image_.domain() == SphericalDomain::Cube && i_out && j_out;
  }

  DomainImage image_;
  std::vector<std::uint32_t> ids_;
  TriMesh mesh_;
  std::set<Edge> edges_;
};

TEST_P(SphericalDomainTest, ImageSizesAndSampleCountsMatchThePaper) {
  const Expected e = expected_layout(image_.domain(), image_.n());
  EXPECT_EQ(image_.width(), e.width);
  EXPECT_EQ(image_.height(), e.height);
  EXPECT_EQ(image_.faces(), e.faces);
  EXPECT_EQ(image_.num_samples(), static_cast<std::size_t>(e.width * e.height * e.faces));
  EXPECT_EQ(image_.num_domain_points(), e.domain_points);
  EXPECT_EQ(static_cast<std::size_t>(*std::max_element(ids_.begin(), ids_.end())) + 1, e.domain_points);
  for (std::size_t k = 0; k < image_.num_samples(); ++k) ASSERT_EQ(image_.linear_index(image_.sample_at(k)), k);
}

TEST_P(SphericalDomainTest, EverySampleMapsToAPointOnTheDomain) {
  for (std::size_t k = 0; k < image_.num_samples(); ++k) {
    const SampleIndex s = image_.sample_at(k);
    ASSERT_TRUE(on_domain(image_.domain(), image_.domain_point(s)))
        << "sample (" << s.face << "," << s.i << "," << s.j << ") -> " << image_.domain_point(s).transpose();
    ASSERT_NEAR(image_.sphere_point(s).norm(), 1.0, 1e-14);
  }
}

TEST_P(SphericalDomainTest, SamePointSamplesHaveTheSameDomainPointAndExtendedNeighbourhood) {
  // Samples identified along the seams are the same point of D, and the extension rules give them the
  // same 4-neighbourhood (as a set of domain points).
  std::vector<std::set<std::uint32_t>> ring(image_.num_domain_points());
  std::vector<bool> seen(image_.num_domain_points(), false);
  std::vector<Vec3> point(image_.num_domain_points());
  for (std::size_t k = 0; k < image_.num_samples(); ++k) {
    const SampleIndex s = image_.sample_at(k);
    const std::set<std::uint32_t> r{id_at(s.face, s.i + 1, s.j), id_at(s.face, s.i - 1, s.j),
                                    id_at(s.face, s.i, s.j + 1), id_at(s.face, s.i, s.j - 1)};
    const std::uint32_t v = ids_[k];
    EXPECT_FALSE(r.count(v)) << "a neighbour resolves to the sample itself at k = " << k;
    if (!seen[v]) {
      seen[v] = true;
      ring[v] = r;
      point[v] = image_.domain_point(s);
      continue;
    }
    ASSERT_EQ(ring[v], r) << "sample (" << s.face << "," << s.i << "," << s.j << ")";
    ASSERT_EQ(point[v], image_.domain_point(s));
  }
}

TEST_P(SphericalDomainTest, ExtendedLatticeNeighboursAreDomainNeighbours) {
  // Every horizontal / vertical step of the extended lattice (offsets up to n beyond every image edge)
  // is an edge of the domain's own triangulation.
  const std::int32_t n = image_.n();
  for (std::int32_t f = 0; f < image_.faces(); ++f)
    for (std::int32_t j = -n; j < image_.height() + n; ++j)
      for (std::int32_t i = -n; i < image_.width() + n; ++i) {
        if (cube_corner_region(i, j)) continue;
        const std::uint32_t a = id_at(f, i, j);
        if (!cube_corner_region(i + 1, j)) {
          ASSERT_TRUE(edges_.count(make_edge(a, id_at(f, i + 1, j)))) << f << " " << i << " " << j << " +i";
        }
        if (!cube_corner_region(i, j + 1)) {
          ASSERT_TRUE(edges_.count(make_edge(a, id_at(f, i, j + 1)))) << f << " " << i << " " << j << " +j";
        }
      }
}

TEST_P(SphericalDomainTest, ExtensionMirrorsAcrossEveryImageEdge) {
  // A lattice position k steps outside an image edge resolves to a sample k steps from that seam on D
  // (graph distance in the domain triangulation), the same distance as the sample k steps inside.
  const std::int32_t n = image_.n();
  for (std::int32_t f = 0; f < image_.faces(); ++f)
    for (const ImageEdge& edge : image_edges(image_, f)) {
      std::vector<std::uint32_t> seam;
      for (const SampleIndex& s : edge.samples) seam.push_back(id_at(s.face, s.i, s.j));
      const std::vector<int> dist = graph_distance(mesh_.num_vertices(), edges_, seam);
      for (const SampleIndex& s : edge.samples)
        for (std::int32_t k = 1; k <= n; ++k) {
          const std::uint32_t outside = id_at(f, s.i + k * edge.di, s.j + k * edge.dj);
          const std::uint32_t inside = id_at(f, s.i - k * edge.di, s.j - k * edge.dj);
          ASSERT_EQ(dist[outside], k) << "face " << f << " sample (" << s.i << "," << s.j << ") k=" << k;
          ASSERT_EQ(dist[inside], k) << "face " << f << " sample (" << s.i << "," << s.j << ") k=" << k;
        }
    }
}

TEST_P(SphericalDomainTest, ReconstructionIsWatertightAtEveryLevel) {
  const auto levels = spherical_lod_levels(static_cast<std::uint32_t>(image_.n()));
  EXPECT_EQ(levels.back(), 1u) << "test resolutions are powers of two";
  for (DomainEmbedding embedding : {DomainEmbedding::Sphere, DomainEmbedding::Polyhedron}) {
    const std::vector<Vec3> positions = domain_positions(image_, embedding);
    for (std::uint32_t level = 0; level < levels.size(); ++level) {
      const TriMesh mesh = reconstruct_spherical_image(image_, positions, level);
      const Expected e = expected_layout(image_.domain(), static_cast<std::int32_t>(levels[level]));
      EXPECT_EQ(mesh.num_vertices(), e.domain_points) << "level " << level;
      EXPECT_EQ(mesh.num_faces(), e.triangles) << "level " << level;
      const TopologyReport t = analyze_topology(mesh);
      EXPECT_TRUE(t.closed && t.manifold && t.oriented) << "level " << level;
      EXPECT_EQ(t.euler_characteristic, 2) << "level " << level;
      EXPECT_EQ(t.components.size(), 1u) << "level " << level;
    }
  }
}

TEST_P(SphericalDomainTest, SphereReconstructionIsOrientedOutward) {
  for (std::size_t v = 0; v < mesh_.num_vertices(); ++v) ASSERT_NEAR(mesh_.positions[v].norm(), 1.0, 1e-12);
  for (std::size_t k = 0; k < ids_.size(); ++k)
    ASSERT_TRUE(mesh_.positions[ids_[k]].isApprox(image_.sphere_point(image_.sample_at(k)), 1e-12));
  for (const Face& f : mesh_.faces) {
    const Vec3& a = mesh_.positions[f[0]];
    const Vec3& b = mesh_.positions[f[1]];
    const Vec3& c = mesh_.positions[f[2]];
    ASSERT_GT((b - a).cross(c - a).dot(a + b + c), 0.0);
  }
}

std::string param_name(const ::testing::TestParamInfo<SphericalDomainTest::ParamType>& info) {
  std::string name(to_string(std::get<0>(info.param)));
  std::replace(name.begin(), name.end(), '-', '_');
  return name + "_n" + std::to_string(std::get<1>(info.param));
}

INSTANTIATE_TEST_SUITE_P(AllDomains, SphericalDomainTest,
                         ::testing::Combine(::testing::ValuesIn(kSphericalDomains),
                                            ::testing::Values(1u, 2u, 4u, 8u, 32u)),
                         param_name);

TEST(SphericalDomain, NamesRoundTrip) {
  for (SphericalDomain d : kSphericalDomains) EXPECT_EQ(parse_spherical_domain(to_string(d)), d);
  EXPECT_EQ(to_string(SphericalDomain::FlatOctahedron), "flat-octa");
  EXPECT_THROW((void)parse_spherical_domain("icosa"), InvalidInput);
}

TEST(SphericalDomain, ExtensionRulesOfThePaper) {
  // Octahedron: 180° rotation about the midpoint of the crossed edge.
  const DomainImage octa(SphericalDomain::Octahedron, 4);
  EXPECT_EQ(octa.resolve(0, 3, -2), (SampleIndex{0, 5, 2}));
  EXPECT_EQ(octa.resolve(0, 9, 1), (SampleIndex{0, 7, 7}));
  EXPECT_EQ(octa.resolve(0, -1, -1), (SampleIndex{0, 7, 7}));
  EXPECT_EQ(octa.resolve(0, 8 + 16, 3 + 16), (SampleIndex{0, 8, 3}));  // the lattice period is 4n
  // Tetrahedron: periodic horizontally, 180° rotations vertically.
  const DomainImage tetra(SphericalDomain::Tetrahedron, 4);
  EXPECT_EQ(tetra.resolve(0, 8, 2), (SampleIndex{0, 0, 2}));
  EXPECT_EQ(tetra.resolve(0, -1, 2), (SampleIndex{0, 7, 2}));
  EXPECT_EQ(tetra.resolve(0, 3, -2), (SampleIndex{0, 5, 2}));
  EXPECT_EQ(tetra.resolve(0, 3, 6), (SampleIndex{0, 5, 2}));
}

TEST(SphericalDomain, CubeExtensionCrossesOntoTheAdjacentFace) {
  // A position k steps outside a cube face edge is the sample k steps (2k/n on D) inside the neighbour.
  for (std::int32_t n : {1, 2, 4, 8, 32}) {
    const DomainImage image(SphericalDomain::Cube, static_cast<std::uint32_t>(n));
    for (std::int32_t f = 0; f < 6; ++f) {
      const Vec3 normal = 0.5 * (image.domain_point({f, 0, 0}) + image.domain_point({f, n, n}));
      for (const ImageEdge& edge : image_edges(image, f))
        for (const SampleIndex& s : edge.samples)
          for (std::int32_t k = 1; k <= n; ++k) {
            const SampleIndex r = image.resolve(f, s.i + k * edge.di, s.j + k * edge.dj);
            ASSERT_NE(r.face, f);
            const Vec3 step = image.domain_point(s) - image.domain_point(r);
            ASSERT_NEAR(step.dot(normal), 2.0 * k / n, 1e-12) << "n=" << n << " face " << f << " k=" << k;
          }
    }
  }
}

TEST(SphericalDomain, RejectsBadInput) {
  EXPECT_THROW(DomainImage(SphericalDomain::Cube, 0), InvalidInput);
  const DomainImage image(SphericalDomain::Octahedron, 6);
  EXPECT_THROW((void)image.resolve(1, 0, 0), InvalidInput);
  const std::vector<Vec3> positions = domain_positions(image, DomainEmbedding::Sphere);
  EXPECT_THROW((void)reconstruct_spherical_image(image, std::span(positions).first(3)), InvalidInput);
  EXPECT_THROW((void)reconstruct_spherical_image(image, positions, 2), InvalidInput);
  EXPECT_NO_THROW((void)reconstruct_spherical_image(image, positions, 1));
  EXPECT_EQ(spherical_lod_levels(12), (std::vector<std::uint32_t>{12, 6, 3}));
}

}  // namespace
}  // namespace gimforge
