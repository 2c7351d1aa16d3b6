#include "kernels/sphere/domain_tables.h"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <mutex>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::detail {
namespace {

constexpr std::size_t kHeaderBytes = 16;
constexpr std::size_t kEntryBytes = 16;
constexpr std::size_t kSampleBytes = 12;
constexpr std::uint32_t kMaxN = 1024;

std::uint32_t load_u32(std::span<const std::byte> b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t k = 0; k < 4; ++k) v |= static_cast<std::uint32_t>(b[at + k]) << (8 * k);
  return v;
}

std::uint64_t load_u64(std::span<const std::byte> b, std::size_t at) {
  return static_cast<std::uint64_t>(load_u32(b, at)) | (static_cast<std::uint64_t>(load_u32(b, at + 4)) << 32);
}

void store_u32(std::vector<std::byte>& out, std::uint32_t v) {
  for (std::size_t k = 0; k < 4; ++k) out.push_back(static_cast<std::byte>((v >> (8 * k)) & 0xffu));
}

void store_u64(std::vector<std::byte>& out, std::uint64_t v) {
  store_u32(out, static_cast<std::uint32_t>(v & 0xffffffffu));
  store_u32(out, static_cast<std::uint32_t>(v >> 32));
}

struct Entry {
  SphericalDomain domain;
  std::uint32_t n;
  std::size_t samples;
};

/// Reads and checks the header and the directory; returns the entries.
std::vector<Entry> parse_directory(std::span<const std::byte> bytes, std::string_view name) {
  if (bytes.size() < kHeaderBytes)
    throw InvalidInput(fmt::format("{}: truncated: {} bytes, shorter than the {}-byte header", name, bytes.size(),
                                   kHeaderBytes));
  if (std::memcmp(bytes.data(), kDomainTablesMagic, sizeof kDomainTablesMagic) != 0)
    throw InvalidInput(fmt::format("{}: wrong magic (not a domain-table file; expected \"GFDTABLE\")", name));
  const std::uint32_t version = load_u32(bytes, 8);
  if (version != kDomainTablesVersion)
    throw InvalidInput(fmt::format("{}: format version {} is not supported (expected {})", name, version,
                                   kDomainTablesVersion));
  const std::uint32_t count = load_u32(bytes, 12);
  if (count < 1 || count > kSphericalDomains.size())
    throw InvalidInput(fmt::format("{}: table count {} is outside 1..{}", name, count, kSphericalDomains.size()));
  const std::size_t data_start = kHeaderBytes + kEntryBytes * count;
  if (bytes.size() < data_start)
    throw InvalidInput(fmt::format("{}: truncated: {} bytes, the directory of {} tables ends at byte {}", name,
                                   bytes.size(), count, data_start));
  std::vector<Entry> entries;
  std::array<bool, kSphericalDomains.size()> seen{};
  std::size_t expected_size = data_start;
  for (std::uint32_t t = 0; t < count; ++t) {
    const std::size_t at = kHeaderBytes + kEntryBytes * t;
    const std::uint32_t id = load_u32(bytes, at), n = load_u32(bytes, at + 4);
    const std::uint64_t samples = load_u64(bytes, at + 8);
    if (id >= kSphericalDomains.size())
      throw InvalidInput(fmt::format("{}: table {}: domain id {} is not a spherical domain (0..{})", name, t, id,
                                     kSphericalDomains.size() - 1));
    const auto domain = static_cast<SphericalDomain>(id);
    if (seen[id]) throw InvalidInput(fmt::format("{}: table {}: a second {} table", name, t, to_string(domain)));
    seen[id] = true;
    if (n < 1 || n > kMaxN)
      throw InvalidInput(fmt::format("{}: table {} ({}): tessellation n = {} is outside 1..{}", name, t,
                                     to_string(domain), n, kMaxN));
    const std::size_t expected = DomainImage(domain, n).num_samples();
    if (samples != expected)
      throw InvalidInput(fmt::format("{}: table {} ({} at n = {}): sample count {} instead of {}", name, t,
                                     to_string(domain), n, samples, expected));
    entries.push_back({domain, n, expected});
    expected_size += kSampleBytes * expected;
  }
  if (bytes.size() != expected_size)
    throw InvalidInput(fmt::format("{}: {}: {} bytes, the directory says {}", name,
                                   bytes.size() < expected_size ? "truncated" : "trailing bytes", bytes.size(),
                                   expected_size));
  return entries;
}

/// Checks that every vector of `t` is finite and of unit length and that samples of one domain point agree.
void check_table(const DomainTableData& t, std::size_t index, std::string_view name) {
  const DomainImage image(t.domain, t.n);
  const std::vector<std::uint32_t> ids = image.vertex_ids();
  std::vector<std::size_t> first(image.num_domain_points(), ids.size());
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const double x = static_cast<double>(t.xyz[3 * k]), y = static_cast<double>(t.xyz[3 * k + 1]),
                 z = static_cast<double>(t.xyz[3 * k + 2]);
    const double length = std::sqrt(x * x + y * y + z * z);
    if (!std::isfinite(length) || std::abs(length - 1.0) > kDomainTablesUnitTolerance)
      throw InvalidInput(fmt::format("{}: table {} ({} at n = {}): sample {} ({}, {}, {}) is not a unit vector", name,
                                     index, to_string(t.domain), t.n, k, x, y, z));
    std::size_t& f = first[ids[k]];
    if (f == ids.size()) {
      f = k;
    } else if (std::memcmp(&t.xyz[3 * f], &t.xyz[3 * k], 3 * sizeof(float)) != 0) {
      throw InvalidInput(fmt::format("{}: table {} ({} at n = {}): samples {} and {} are the same domain point but "
                                     "hold different vectors",
                                     name, index, to_string(t.domain), t.n, f, k));
    }
  }
}

}  // namespace

std::vector<DomainTableData> parse_domain_tables(std::span<const std::byte> bytes, std::string_view name) {
  const std::vector<Entry> entries = parse_directory(bytes, name);
  std::vector<DomainTableData> tables;
  std::size_t at = kHeaderBytes + kEntryBytes * entries.size();
  for (std::size_t t = 0; t < entries.size(); ++t) {
    DomainTableData d{entries[t].domain, entries[t].n, std::vector<float>(3 * entries[t].samples)};
    for (float& v : d.xyz) {
      v = std::bit_cast<float>(load_u32(bytes, at));
      at += 4;
    }
    check_table(d, t, name);
    tables.push_back(std::move(d));
  }
  return tables;
}

std::vector<std::byte> encode_domain_tables(std::span<const DomainSphereMap> maps) {
  if (maps.empty() || maps.size() > kSphericalDomains.size())
    throw InvalidInput(fmt::format("encode_domain_tables: {} maps, expected 1..{}", maps.size(),
                                   kSphericalDomains.size()));
  std::size_t samples = 0;
  for (const DomainSphereMap& m : maps) samples += m.sphere.size();
  std::vector<std::byte> out;
  out.reserve(kHeaderBytes + kEntryBytes * maps.size() + kSampleBytes * samples);
  for (const char c : kDomainTablesMagic) out.push_back(static_cast<std::byte>(c));
  store_u32(out, kDomainTablesVersion);
  store_u32(out, static_cast<std::uint32_t>(maps.size()));
  std::array<bool, kSphericalDomains.size()> seen{};
  for (const DomainSphereMap& m : maps) {
    const auto id = static_cast<std::size_t>(m.domain);
    if (seen[id]) throw InvalidInput(fmt::format("encode_domain_tables: a second {} map", to_string(m.domain)));
    seen[id] = true;
    const std::size_t expected = DomainImage(m.domain, m.n).num_samples();
    if (m.sphere.size() != expected)
      throw InvalidInput(fmt::format("encode_domain_tables: the {} map at n = {} has {} vectors, expected {}",
                                     to_string(m.domain), m.n, m.sphere.size(), expected));
    store_u32(out, static_cast<std::uint32_t>(id));
    store_u32(out, m.n);
    store_u64(out, m.sphere.size());
  }
  for (const DomainSphereMap& m : maps)
    for (const Vec3& v : m.sphere)
      for (int c = 0; c < 3; ++c) store_u32(out, std::bit_cast<std::uint32_t>(static_cast<float>(v[c])));
  return out;
}

std::span<const DomainTableData> domain_tables() {
  static std::once_flag once;
  static std::vector<DomainTableData> tables;
  std::call_once(once, [] {
    tables = parse_domain_tables(embedded_domain_tables(), "built-in domain tables (kernels/sphere/domain_tables.bin)");
  });
  return tables;
}

}  // namespace gimforge::detail
