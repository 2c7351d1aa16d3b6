// The built-in domain tables: the binary format of kernels/sphere/domain_tables.bin (domain_tables.h), its
// encoder and its validating parser, and the blob embedded into gimforge_sphere.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/sphere/domain_map.h"
#include "kernels/sphere/domain_tables.h"
#include "tests/unit/test_support.h"

namespace gimforge {
namespace {

using detail::encode_domain_tables;
using detail::parse_domain_tables;
using test::message_of;

using Blob = std::vector<std::byte>;

/// Gnomonic maps of all four domains at n = 2: a small valid blob.
Blob small_blob() {
  std::vector<DomainSphereMap> maps;
  for (SphericalDomain d : kSphericalDomains) maps.push_back(gnomonic_domain_map(d, 2));
  return encode_domain_tables(maps);
}

std::uint32_t get_u32(const Blob& b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t k = 0; k < 4; ++k) v |= static_cast<std::uint32_t>(b[at + k]) << (8 * k);
  return v;
}

void set_u32(Blob& b, std::size_t at, std::uint32_t v) {
  for (std::size_t k = 0; k < 4; ++k) b[at + k] = static_cast<std::byte>((v >> (8 * k)) & 0xffu);
}

/// Byte offset of the first sample of table 0 in a blob of `tables` tables.
std::size_t data_start(std::size_t tables) { return 16 + 16 * tables; }

/// The parser's message for `blob`, which must be rejected with InvalidInput.
std::string rejection(const Blob& blob) {
  const std::string m = message_of<InvalidInput>([&] { (void)parse_domain_tables(blob, "test.bin"); });
  EXPECT_EQ(m.rfind("test.bin: ", 0), 0u) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  return m;
}

TEST(DomainTables, EncodingFollowsTheDocumentedLayout) {
  const Blob b = small_blob();
  EXPECT_EQ(std::memcmp(b.data(), "GFDTABLE", 8), 0);
  EXPECT_EQ(get_u32(b, 8), 1u);
  EXPECT_EQ(get_u32(b, 12), 4u);
  std::size_t at = data_start(4), samples = 0;
  for (std::size_t t = 0; t < 4; ++t) {
    const DomainImage image(kSphericalDomains[t], 2);
    EXPECT_EQ(get_u32(b, 16 + 16 * t), static_cast<std::uint32_t>(kSphericalDomains[t]));
    EXPECT_EQ(get_u32(b, 20 + 16 * t), 2u);
    EXPECT_EQ(get_u32(b, 24 + 16 * t), image.num_samples());
    EXPECT_EQ(get_u32(b, 28 + 16 * t), 0u);
    // First sample of each table: float32 x, y, z little-endian.
    const Vec3 v = gnomonic_domain_map(kSphericalDomains[t], 2).sphere[0];
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(get_u32(b, at + 4 * static_cast<std::size_t>(c)), std::bit_cast<std::uint32_t>(static_cast<float>(v[c])));
    at += 12 * image.num_samples();
    samples += image.num_samples();
  }
  EXPECT_EQ(b.size(), data_start(4) + 12 * samples);
}

TEST(DomainTables, ParseReturnsTheEncodedFloats) {
  std::vector<DomainSphereMap> maps;
  for (SphericalDomain d : {SphericalDomain::Cube, SphericalDomain::Tetrahedron}) maps.push_back(gnomonic_domain_map(d, 5));
  const std::vector<detail::DomainTableData> t = parse_domain_tables(encode_domain_tables(maps), "test.bin");
  ASSERT_EQ(t.size(), 2u);
  for (std::size_t m = 0; m < 2; ++m) {
    EXPECT_EQ(t[m].domain, maps[m].domain);
    EXPECT_EQ(t[m].n, 5u);
    ASSERT_EQ(t[m].xyz.size(), 3 * maps[m].sphere.size());
    for (std::size_t k = 0; k < maps[m].sphere.size(); ++k)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(t[m].xyz[3 * k + static_cast<std::size_t>(c)], static_cast<float>(maps[m].sphere[k][c]));
  }
}

TEST(DomainTables, EmbeddedBlobHoldsAllFourDomainsAtN64) {
  const std::span<const std::byte> blob = detail::embedded_domain_tables();
  const std::vector<detail::DomainTableData> parsed = parse_domain_tables(blob, "embedded");
  ASSERT_EQ(parsed.size(), kSphericalDomains.size());
  std::size_t samples = 0;
  for (std::size_t t = 0; t < parsed.size(); ++t) {
    EXPECT_EQ(parsed[t].domain, kSphericalDomains[t]);
    EXPECT_EQ(parsed[t].n, 64u);
    samples += parsed[t].xyz.size() / 3;
    // builtin_domain_map serves exactly these vectors (normalized in double).
    const DomainSphereMap& m = builtin_domain_map(parsed[t].domain);
    ASSERT_EQ(m.sphere.size(), parsed[t].xyz.size() / 3);
    for (std::size_t k = 0; k < m.sphere.size(); k += 97) {
      const Vec3 f(static_cast<double>(parsed[t].xyz[3 * k]), static_cast<double>(parsed[t].xyz[3 * k + 1]),
                   static_cast<double>(parsed[t].xyz[3 * k + 2]));
      EXPECT_EQ(m.sphere[k], f.normalized());
    }
  }
  EXPECT_EQ(blob.size(), data_start(4) + 12 * samples);
  EXPECT_EQ(detail::domain_tables().size(), kSphericalDomains.size());
}

TEST(DomainTables, RejectsTruncatedBlobs) {
  EXPECT_NE(rejection({}).find("truncated"), std::string::npos);
  const Blob b = small_blob();
  EXPECT_NE(rejection(Blob(b.begin(), b.begin() + 12)).find("shorter than the 16-byte header"), std::string::npos);
  EXPECT_NE(rejection(Blob(b.begin(), b.begin() + 40)).find("directory of 4 tables"), std::string::npos);
  EXPECT_NE(rejection(Blob(b.begin(), b.end() - 1)).find("truncated"), std::string::npos);
  const std::span<const std::byte> e = detail::embedded_domain_tables();
  EXPECT_NE(rejection(Blob(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2))).find("truncated"),
            std::string::npos);
  Blob longer = b;
  longer.push_back(std::byte{0});
  EXPECT_NE(rejection(longer).find("trailing bytes"), std::string::npos);
}

TEST(DomainTables, RejectsWrongMagicAndVersion) {
  Blob b = small_blob();
  b[3] = std::byte{'X'};
  EXPECT_NE(rejection(b).find("wrong magic"), std::string::npos);
  b = small_blob();
  set_u32(b, 8, 2);
  EXPECT_NE(rejection(b).find("format version 2 is not supported"), std::string::npos);
}

TEST(DomainTables, RejectsWrongCounts) {
  Blob b = small_blob();
  set_u32(b, 12, 0);
  EXPECT_NE(rejection(b).find("table count 0 is outside 1..4"), std::string::npos);
  set_u32(b, 12, 5);
  EXPECT_NE(rejection(b).find("table count 5"), std::string::npos);
  set_u32(b, 12, 3);  // one table fewer than the data holds
  EXPECT_NE(rejection(b).find("trailing bytes"), std::string::npos);
  b = small_blob();
  set_u32(b, 24 + 16, get_u32(b, 24 + 16) + 1);  // the tetrahedron's sample count
  EXPECT_NE(rejection(b).find("table 1 (tetra at n = 2): sample count"), std::string::npos);
  b = small_blob();
  set_u32(b, 28, 1);  // high word of the octahedron's 64-bit sample count
  EXPECT_NE(rejection(b).find("table 0 (octa at n = 2): sample count"), std::string::npos);
}

TEST(DomainTables, RejectsBadDirectoryEntries) {
  Blob b = small_blob();
  set_u32(b, 16 + 16 * 2, 7);
  EXPECT_NE(rejection(b).find("table 2: domain id 7 is not a spherical domain"), std::string::npos);
  b = small_blob();
  set_u32(b, 16 + 16 * 3, 0);  // flat-octa entry claims octa
  EXPECT_NE(rejection(b).find("table 3: a second octa table"), std::string::npos);
  b = small_blob();
  set_u32(b, 20, 0);
  EXPECT_NE(rejection(b).find("n = 0 is outside 1..1024"), std::string::npos);
  set_u32(b, 20, 5000);
  EXPECT_NE(rejection(b).find("n = 5000 is outside 1..1024"), std::string::npos);
}

TEST(DomainTables, RejectsVectorsThatAreNotUnitOrDisagree) {
  const std::size_t start = data_start(4);
  Blob b = small_blob();
  set_u32(b, start + 12 * 3, std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_NE(rejection(b).find("table 0 (octa at n = 2): sample 3 (nan"), std::string::npos);
  b = small_blob();
  const float x = std::bit_cast<float>(get_u32(b, start + 12 * 4));
  set_u32(b, start + 12 * 4, std::bit_cast<std::uint32_t>(x * 1.01f + 0.01f));
  EXPECT_NE(rejection(b).find("sample 4"), std::string::npos);
  EXPECT_NE(rejection(b).find("is not a unit vector"), std::string::npos);
  // Two stored samples of one domain point (the octahedron image's mirrored border) with different
  // unit vectors: swap the coordinates of the second one.
  b = small_blob();
  const std::vector<std::uint32_t> ids = DomainImage(SphericalDomain::Octahedron, 2).vertex_ids();
  std::vector<bool> seen(ids.size(), false);
  std::size_t second = ids.size();
  for (std::size_t k = 0; k < ids.size() && second == ids.size(); ++k) {
    if (seen[ids[k]]) second = k;
    seen[ids[k]] = true;
  }
  ASSERT_LT(second, ids.size());
  const std::uint32_t xb = get_u32(b, start + 12 * second), yb = get_u32(b, start + 12 * second + 4),
                      zb = get_u32(b, start + 12 * second + 8);
  ASSERT_FALSE(xb == yb && yb == zb);
  set_u32(b, start + 12 * second, zb);
  set_u32(b, start + 12 * second + 4, xb);
  set_u32(b, start + 12 * second + 8, yb);
  EXPECT_NE(rejection(b).find("are the same domain point but hold different vectors"), std::string::npos);
}

TEST(DomainTables, EncoderRejectsInconsistentMaps) {
  DomainSphereMap m = gnomonic_domain_map(SphericalDomain::Cube, 3);
  m.sphere.pop_back();
  EXPECT_NE(message_of<InvalidInput>([&] { (void)encode_domain_tables(std::vector{m}); }).find("has 95 vectors, expected 96"),
            std::string::npos);
  const DomainSphereMap a = gnomonic_domain_map(SphericalDomain::Cube, 3);
  EXPECT_NE(message_of<InvalidInput>([&] { (void)encode_domain_tables(std::vector{a, a}); }).find("a second cube map"),
            std::string::npos);
}

}  // namespace
}  // namespace gimforge
