/// \file representation.cpp
/// Representation groups of the archive (see representation.h and docs/archive.md).
#include "io/representation.h"

#include <algorithm>
#include <array>

#include <fmt/format.h>

#include "io/printable.h"

namespace gimforge::io {
namespace {

std::string group_path(const RepresentationKind& kind, const std::string& name) {
  return fmt::format("{}/{}", kind.group, name);
}

std::string shape_string(const h5::Dims& shape) {
  return shape.size() == 1 ? fmt::format("({},)", shape.front()) : fmt::format("({})", fmt::join(shape, ", "));
}

}  // namespace

void check_representation_name(const RepresentationKind& kind, const std::string& name, bool existing) {
  // Names are printed, become preview file names and are read by other people's tools: one file-name
  // component without control characters (io/printable.h).
  if (const std::string problem = path_component_problem(name, !existing); !problem.empty())
    throw InvalidInput(fmt::format("invalid {} name '{}': it {} (non-empty, not '.' or '..', no '/' or control "
                                   "characters, at most {} bytes)",
                                   kind.what, printable(name), problem, kMaxPathComponent));
}

h5::Group create_representation(Archive& archive, const RepresentationKind& kind, const std::string& name) {
  check_representation_name(kind, name);
  h5::Group parent = archive.root().require_group(kind.group);
  return parent.create_group(name);
}

h5::Group open_representation(const Archive& archive, const RepresentationKind& kind, const std::string& name) {
  check_representation_name(kind, name, /*existing=*/true);
  if (!archive.root().exists(group_path(kind, name)))
  {
    const std::vector<std::string> names = representation_names(archive, kind);
    throw FormatError(fmt::format("{}: no {} '{}' ({})", archive.path().string(), kind.what, name,
                                  names.empty() ? fmt::format("it holds no {}", kind.what)
                                                : fmt::format("has: {}", fmt::join(names, ", "))));
  }
  return archive.root().open_group(group_path(kind, name));
}

std::vector<std::string> representation_names(const Archive& archive, const RepresentationKind& kind) {
  if (!archive.root().exists(kind.group)) return {};
  return archive.root().open_group(kind.group).children();
}

void check_record(const RepresentationRecord& record, std::initializer_list<std::string_view> structural) {
  const auto reserved = [&](std::string_view key) {
    return key == "method" || key == "source" ||
           std::find(structural.begin(), structural.end(), key) != structural.end();
  };
  for (const auto& entry : record.numbers)
    if (reserved(entry.first))
      throw InvalidInput(fmt::format("record number '{}' would overwrite the attribute of that name", entry.first));
}

void write_record(h5::Group& group, std::string_view method, const RepresentationRecord& record) {
  group.set_attribute("method", method);
  group.set_attribute("source", record.source);
  for (const auto& [key, value] : record.numbers) {
    if (group.has_attribute(key))
      throw InvalidInput(fmt::format("{}: record number '{}' would overwrite the attribute of that name",
                                     group.path(), key));
    group.set_attribute(key, value);
  }
}

RepresentationRecord read_record(const h5::Group& group) {
  RepresentationRecord r;
  r.source = group.attribute<std::string>("source");
  for (const std::string& key : group.attribute_names()) {
    try {
      r.numbers[key] = group.attribute<double>(key);
    } catch (const FormatError&) {
      // a structural attribute (string, integer or array): not a number of the record
    }
  }
  return r;
}

void check_method(const h5::Group& group, const Archive& archive, const RepresentationKind& kind,
                  const std::string& name, std::string_view method) {
  const auto stored = group.attribute<std::string>("method");
  if (stored != method)
    throw representation_error(archive, kind, name, fmt::format("method is '{}', expected '{}'", stored, method));
}

h5::Dataset open_item(const h5::Group& group, const Archive& archive, const RepresentationKind& kind,
                      const std::string& name, std::string_view item) {
  if (group.exists(item)) {
    try {
      return group.open_dataset(item);
    } catch (const LibraryError& e) {
      throw representation_error(archive, kind, name, dataset_open_failure(item, e));
    }
  }
  throw representation_error(archive, kind, name, fmt::format("no dataset '{}'", item));
}

std::string dataset_open_failure(std::string_view item, const LibraryError& error) {
  const std::string_view what = error.what();
  constexpr std::string_view kMarker = "cannot open dataset: ";
  const std::size_t at = what.find(kMarker);
  const std::string_view cause = at == std::string_view::npos ? what : what.substr(at + kMarker.size());
  if (cause.find("checksum") != std::string_view::npos || cause.find("version number") != std::string_view::npos)
    return fmt::format("'{}' is damaged (HDF5: {})", item, cause);
  return fmt::format("'{}' is not a dataset", item);
}

void check_shape(const h5::Dataset& dataset, const Archive& archive, const RepresentationKind& kind,
                 const std::string& name, std::string_view item, const h5::Dims& expected) {
  const h5::Dims shape = dataset.shape();
  if (shape != expected)
    throw representation_error(archive, kind, name,
                               fmt::format("dataset '{}' has shape {}, expected {}", item, shape_string(shape),
                                           shape_string(expected)));
}

FormatError representation_error(const Archive& archive, const RepresentationKind& kind, const std::string& name,
                                 std::string_view cause) {
  return FormatError(fmt::format("{}: {} '{}': {}", archive.path().string(), kind.what, name, cause));
}

std::vector<float> read_sample_uv(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                                  const std::string& name, std::uint64_t n) {
  const h5::Dataset ds = open_item(g, archive, kind, name, "sample_uv");
  const h5::Dims shape = ds.shape();
  if (shape.size() != 3 || shape[0] != n || shape[1] != n || shape[2] != 2)
    throw representation_error(archive, kind, name, fmt::format("dataset 'sample_uv' should have shape ({0}, {0}, 2)", n));
  if (ds.dtype() != h5::DType::kFloat32)
    throw representation_error(archive, kind, name, "dataset 'sample_uv' is not float32");
  std::vector<float> values = ds.read<float>();
  const auto bad = std::find_if_not(values.begin(), values.end(), [](float v) { return v >= 0.0f && v <= 1.0f; });
  if (bad != values.end())
    throw representation_error(archive, kind, name,
                               fmt::format("sample {} of dataset 'sample_uv' is {} (parameter points lie in [0, 1])",
                                           static_cast<std::size_t>(bad - values.begin()) / 2, *bad));
  // The grid the writer keeps: boundary pixels on their side of the square, every quad strictly convex.
  const auto at = [&](std::uint64_t i, std::uint64_t j, int c) { return double{values[(j * n + i) * 2 + static_cast<std::uint64_t>(c)]}; };
  for (std::uint64_t k = 0; k < n; ++k)
    if (at(k, 0, 1) != 0.0 || at(k, n - 1, 1) != 1.0 || at(0, k, 0) != 0.0 || at(n - 1, k, 0) != 1.0)
      throw representation_error(archive, kind, name,
                                 fmt::format("dataset 'sample_uv': boundary sample {} is off its side of the square", k));
  for (std::uint64_t j = 0; j + 1 < n; ++j)
    for (std::uint64_t i = 0; i + 1 < n; ++i) {
      const std::array<std::pair<std::uint64_t, std::uint64_t>, 4> q{{{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}}};
      for (std::size_t e = 0; e < 4; ++e) {
        const auto [i0, j0] = q[e];
        const auto [i1, j1] = q[(e + 1) % 4];
        const auto [i2, j2] = q[(e + 2) % 4];
        const double cross = (at(i1, j1, 0) - at(i0, j0, 0)) * (at(i2, j2, 1) - at(i0, j0, 1)) -
                             (at(i1, j1, 1) - at(i0, j0, 1)) * (at(i2, j2, 0) - at(i0, j0, 0));
        if (!(cross > 0.0))
          throw representation_error(archive, kind, name,
                                     fmt::format("dataset 'sample_uv': the quad at pixel ({}, {}) is folded", j, i));
      }
    }
  return values;
}

std::vector<std::uint8_t> read_roi_mask(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                                        const std::string& name, std::uint64_t n) {
  if (!g.exists("roi_mask")) return {};
  const h5::Dataset ds = open_item(g, archive, kind, name, "roi_mask");
  if (ds.dtype() != h5::DType::kUInt8 || ds.shape() != h5::Dims{n, n}) {
    std::string shape;
    for (const std::uint64_t d : ds.shape()) shape += (shape.empty() ? "" : ", ") + std::to_string(d);
    throw representation_error(archive, kind, name,
                               fmt::format("dataset 'roi_mask' should be uint8 ({0}, {0}), not {1} ({2})", n,
                                           ds.dtype() == h5::DType::kUInt8 ? "uint8" : "another type", shape));
  }
  std::vector<std::uint8_t> roi = ds.read<std::uint8_t>();
  if (const auto bad = std::find_if(roi.begin(), roi.end(), [](std::uint8_t v) { return v > 1; }); bad != roi.end())
    throw representation_error(archive, kind, name,
                               fmt::format("dataset 'roi_mask' holds {} at {} (flags are 0 or 1)", int{*bad}, bad - roi.begin()));
  return roi;
}

}  // namespace gimforge::io
