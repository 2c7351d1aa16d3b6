#pragma once
/// \file domain_tables.h
/// Internal: the built-in stretch-optimized D → S tables, read through builtin_domain_map in domain_map.h.
/// They are the binary file kernels/sphere/domain_tables.bin, made by tools/domain_tables (the generator)
/// and embedded into gimforge_sphere at build time (domain_tables_embed.cpp, `.incbin`): no file is read
/// at run time.
///
/// Format (version 1, every field little-endian):
///
///     offset  size        field
///     0       8           magic "GFDTABLE"
///     8       4           u32 format version (1)
///     12      4           u32 table count T (1..4, at most one table per domain)
///     16      16·T        per table: u32 domain id (SphericalDomain value: 0 octa, 1 tetra, 2 cube,
///                         3 flat-octa), u32 tessellation n, u64 sample count S (= DomainImage(domain,
///                         n).num_samples())
///     16+16T  12·ΣS       the tables in directory order: per sample float32 x, y, z (a unit vector), in
///                         DomainImage linear_index order
///
/// Nothing may follow the last table. Samples that are the same domain point hold the same vector.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/sphere/domain_map.h"
#include "kernels/sphere/spherical_domain.h"

namespace gimforge::detail {

/// One table: the unit vectors (x, y, z as float) of every stored sample of DomainImage(domain, n).
struct DomainTableData {
  SphericalDomain domain;
  std::uint32_t n;
  std::vector<float> xyz;  ///< 3 · DomainImage(domain, n).num_samples() values
};

inline constexpr char kDomainTablesMagic[8] = {'G', 'F', 'D', 'T', 'A', 'B', 'L', 'E'};
inline constexpr std::uint32_t kDomainTablesVersion = 1;
/// Largest allowed deviation of a stored vector's length from 1 (float rounding of a unit vector is ~1e-7).
inline constexpr double kDomainTablesUnitTolerance = 1e-5;

/// Parses and validates a domain-table blob (the format above): magic, version, table count, domain ids
/// (valid, no duplicates), n in 1..1024, sample counts equal to DomainImage(domain, n).num_samples(),
/// total size exactly as the directory says, every value finite, every vector of unit length within
/// kDomainTablesUnitTolerance, samples of one domain point equal. `name` names the blob in messages.
/// Throws InvalidInput "NAME: CAUSE" (one line) for any violation.
[[nodiscard]] std::vector<DomainTableData> parse_domain_tables(std::span<const std::byte> bytes,
                                                               std::string_view name);

/// Encodes `maps` (each vector rounded to float32) in the format above, in the given order. Throws
/// InvalidInput when a map's size does not match DomainImage(domain, n) or a domain appears twice.
[[nodiscard]] std::vector<std::byte> encode_domain_tables(std::span<const DomainSphereMap> maps);

/// The embedded bytes of kernels/sphere/domain_tables.bin (domain_tables_embed.cpp).
[[nodiscard]] std::span<const std::byte> embedded_domain_tables();

/// All built-in tables (at most one per domain): the embedded blob, parsed and validated once (thread
/// safe). Throws InvalidInput "built-in domain tables (kernels/sphere/domain_tables.bin): CAUSE" when the
/// embedded file is corrupt.
[[nodiscard]] std::span<const DomainTableData> domain_tables();

}  // namespace gimforge::detail
