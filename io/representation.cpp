/// \file representation.cpp
/// Representation groups of the archive (see representation.h and docs/archive.md).
#include "io/representation.h"

#include <algorithm>

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

void check_representation_name(const RepresentationKind& kind, const std::string& name) {
  // Names are printed, become preview file names and are read by other people's tools: one file-name
  // component without control characters (io/printable.h).
  if (!path_component_problem(name).empty())
    throw InvalidInput(fmt::format("invalid {} name '{}' (non-empty, not '.' or '..', no '/' or control characters)",
                                   kind.what, printable(name)));
}

h5::Group create_representation(Archive& archive, const RepresentationKind& kind, const std::string& name) {
  check_representation_name(kind, name);
  h5::Group parent = archive.root().require_group(kind.group);
  return parent.create_group(name);
}

h5::Group open_representation(const Archive& archive, const RepresentationKind& kind, const std::string& name) {
  check_representation_name(kind, name);
  if (!archive.root().exists(group_path(kind, name)))
    throw FormatError(fmt::format("{}: no {} '{}' (has: {})", archive.path().string(), kind.what, name,
                                  fmt::join(representation_names(archive, kind), ", ")));
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
    } catch (const LibraryError&) {
      throw representation_error(archive, kind, name, fmt::format("'{}' is not a dataset", item));
    }
  }
  throw representation_error(archive, kind, name, fmt::format("no dataset '{}'", item));
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

}  // namespace gimforge::io
