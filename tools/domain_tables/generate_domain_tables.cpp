// generate_domain_tables: makes kernels/sphere/domain_tables.bin, the built-in stretch-optimized D -> S maps
// of the four spherical domains (Praun & Hoppe 2003, section 4.2), embedded into gimforge_sphere.
//
//   generate_domain_tables [--n N] [--write FILE.bin | --check FILE.bin] [--tolerance T]
//
// Optimizes every domain's map at tessellation N (default 64) with the default DomainMapOptions (seed 1),
// printing each one's L2 stretch efficiency next to the paper's Table 2. --write stores the tables (format:
// kernels/sphere/domain_tables.h) atomically; --check compares them with FILE.bin instead and fails unless
// every float is within T (default 0: bit-identical) of the file's. A developer tool, not part of the CLI.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/domain_map.h"
#include "kernels/sphere/domain_tables.h"

namespace {

using namespace gimforge;

constexpr int kExitOk = 0, kExitError = 1, kExitUsage = 2;

constexpr std::string_view kUsage =
    "usage: generate_domain_tables [--n N] [--write FILE.bin | --check FILE.bin] [--tolerance T]\n"
    "  --n N          tessellation of the optimization, 1..1024 (default 64, the built-in tables)\n"
    "  --write FILE   write the tables of all four domains to FILE (atomically)\n"
    "  --check FILE   regenerate in memory and compare with FILE; exit 1 if a float differs by more than T\n"
    "  --tolerance T  largest allowed |difference| per float for --check (default 0: bit-identical)\n";

struct Options {
  std::uint32_t n{64};
  std::string write;
  std::string check;
  double tolerance{0.0};
};

/// Thrown for a malformed command line (exit 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

Options parse_args(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage.data(), stdout);
      std::exit(kExitOk);
    }
    if (a != "--n" && a != "--write" && a != "--check" && a != "--tolerance")
      throw UsageError(fmt::format("unknown option {}", a));
    if (i + 1 >= argc) throw UsageError(fmt::format("{} needs a value", a));
    const std::string v = argv[++i];
    if (a == "--n") {
      std::size_t used = 0;
      unsigned long n = 0;
      try {
        n = std::stoul(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != v.size() || n < 1 || n > 1024) throw UsageError(fmt::format("--n {}: expected an integer in 1..1024", v));
      o.n = static_cast<std::uint32_t>(n);
    } else if (a == "--write") {
      o.write = v;
    } else if (a == "--check") {
      o.check = v;
    } else if (a == "--tolerance") {
      std::size_t used = 0;
      try {
        o.tolerance = std::stod(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != v.size() || !(o.tolerance >= 0.0)) throw UsageError(fmt::format("--tolerance {}: expected a number >= 0", v));
    }
  }
  if (!o.write.empty() && !o.check.empty()) throw UsageError("--write and --check exclude each other");
  return o;
}

std::vector<std::byte> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot open for reading", path));
  std::vector<char> chars((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError(fmt::format("{}: read failed", path));
  std::vector<std::byte> bytes(chars.size());
  std::memcpy(bytes.data(), chars.data(), chars.size());
  return bytes;
}

void write_file(const std::string& path, const std::vector<std::byte>& bytes) {
  io::write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError(fmt::format("{}: cannot open for writing", tmp.string()));
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw IoError(fmt::format("{}: write failed", tmp.string()));
  });
}

/// Compares the regenerated tables with `want` (the tables of `path`); prints per table the largest
/// |difference| of a float and how many differ. Returns whether all are within `tolerance`.
bool check_against(const std::string& path, const std::vector<detail::DomainTableData>& want,
                   const std::vector<std::byte>& generated, double tolerance) {
  const std::vector<detail::DomainTableData> got = detail::parse_domain_tables(generated, "regenerated tables");
  if (want.size() != got.size()) {
    std::fputs(fmt::format("{}: {} tables, regenerated {}\n", path, want.size(), got.size()).c_str(), stderr);
    return false;
  }
  bool ok = true;
  double overall = 0.0;
  for (std::size_t t = 0; t < want.size(); ++t) {
    if (want[t].domain != got[t].domain || want[t].n != got[t].n) {
      std::fputs(fmt::format("{}: table {} is {} at n = {}, regenerated {} at n = {}\n", path, t,
                             to_string(want[t].domain), want[t].n, to_string(got[t].domain), got[t].n)
                     .c_str(),
                 stderr);
      ok = false;
      continue;
    }
    double max_dev = 0.0;
    std::size_t differ = 0;
    for (std::size_t k = 0; k < want[t].xyz.size(); ++k) {
      if (std::memcmp(&want[t].xyz[k], &got[t].xyz[k], sizeof(float)) == 0) continue;
      ++differ;
      max_dev = std::max(max_dev, std::abs(static_cast<double>(want[t].xyz[k]) - static_cast<double>(got[t].xyz[k])));
    }
    overall = std::max(overall, max_dev);
    ok = ok && max_dev <= tolerance;
    fmt::print("check {:<10} {} of {} floats differ, max |difference| {:.3g}\n", to_string(got[t].domain), differ,
               want[t].xyz.size(), max_dev);
  }
  fmt::print("check {}: max deviation {:.3g} (tolerance {:.3g}): {}\n", path, overall, tolerance,
             ok ? "ok" : "MISMATCH");
  return ok;
}

int run(const Options& o) {
  // The file to check is read and validated first: a missing or corrupt one fails before the optimization.
  std::vector<detail::DomainTableData> committed;
  if (!o.check.empty()) committed = detail::parse_domain_tables(read_file(o.check), o.check);
  std::vector<DomainSphereMap> maps;
  double total = 0.0;
  for (SphericalDomain d : kSphericalDomains) {
    const auto t0 = std::chrono::steady_clock::now();
    maps.push_back(optimize_domain_map(d, o.n, DomainMapOptions{}));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    total += seconds;
    const double efficiency = domain_map_stretch(maps.back()).efficiency;
    const double gnomonic = domain_map_stretch(gnomonic_domain_map(d, o.n)).efficiency;
    fmt::print("{:<10} n = {:<4} L2 stretch efficiency {:.4f} (paper Table 2: {:.3f}, {:+.4f}; gnomonic {:.4f})  {:.1f} s\n",
               to_string(d), o.n, efficiency, paper_domain_efficiency(d), efficiency - paper_domain_efficiency(d),
               gnomonic, seconds);
    std::fflush(stdout);
  }
  fmt::print("optimized all {} domains in {:.1f} s\n", maps.size(), total);
  const std::vector<std::byte> bytes = detail::encode_domain_tables(maps);
  if (!o.write.empty()) {
    write_file(o.write, bytes);
    fmt::print("wrote {} ({} bytes; rebuild gimforge_sphere to embed it)\n", o.write, bytes.size());
  }
  if (!o.check.empty() && !check_against(o.check, committed, bytes, o.tolerance)) return kExitError;
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse_args(argc, argv));
  } catch (const UsageError& e) {
    std::fputs(fmt::format("generate_domain_tables: {}\n{}", e.what(), kUsage).c_str(), stderr);
    return kExitUsage;
  } catch (const std::exception& e) {
    std::fputs(fmt::format("generate_domain_tables: error: {}\n", e.what()).c_str(), stderr);
    return kExitError;
  }
}
