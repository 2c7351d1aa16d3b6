#pragma once
/// \file representation.h
/// What every representation group of the archive shares (docs/archive.md, "Representations"): a group
/// /<kind>/<name> (e.g. /gim/bunny, /spherical/bunny) holding the representation's datasets, whose
/// attributes record the method, the source mesh and a map of numbers (fidelity, statistics, timings).
/// gim_archive.h and sphere_archive.h build on these helpers.
#include <initializer_list>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "io/archive.h"
#include "kernels/core/errors.h"

namespace gimforge::io {

/// Scalar facts stored as attributes of a representation group next to its datasets: `source` as a
/// string attribute, every number as a float64 attribute of the same name.
struct RepresentationRecord {
  std::string source;                      ///< input mesh path
  std::map<std::string, double> numbers;   ///< e.g. "psnr", "hausdorff_rms", "seconds_total"
};

/// Where a kind of representation lives and what messages call it: `group` is the child of the root
/// ("gim", "spherical"), `what` the human name ("geometry image", "spherical geometry image").
struct RepresentationKind {
  std::string_view group;
  std::string_view what;
};

/// Throws InvalidInput "invalid <what> name 'NAME' (non-empty, not '.' or '..', no '/' or control characters)"
/// (NAME escaped with io::printable) unless `name` is one non-empty HDF5 link name other than "." and ".."
/// without control characters or invalid UTF-8 (io::path_component_problem).
/// `existing`: a name read from an archive, which an earlier gimforge may have written longer than
/// kMaxPathComponent: only new names are held to it.
void check_representation_name(const RepresentationKind& kind, const std::string& name, bool existing = false);

/// Creates the group /<kind.group>/<name> (and /<kind.group> when absent). Throws InvalidInput for a bad
/// name, LibraryError when the group exists or HDF5 fails.
[[nodiscard]] h5::Group create_representation(Archive& archive, const RepresentationKind& kind,
                                              const std::string& name);

/// Opens the group /<kind.group>/<name>. Throws InvalidInput for a bad name and FormatError
/// "ARCHIVE: no <what> 'NAME' (has: a, b)" when the archive holds no such representation.
[[nodiscard]] h5::Group open_representation(const Archive& archive, const RepresentationKind& kind,
                                            const std::string& name);

/// Names of the representations of one kind (children of /<kind.group>), sorted; empty when none.
[[nodiscard]] std::vector<std::string> representation_names(const Archive& archive, const RepresentationKind& kind);

/// Throws InvalidInput when a number of `record` is called "method", "source" or one of the
/// representation's `structural` attribute names (it would overwrite them). Writers call it before they
/// create anything.
void check_record(const RepresentationRecord& record, std::initializer_list<std::string_view> structural);

/// Writes the attributes `method` and `source` and every number of `record` (float64) on `group`. Write
/// the structural attributes first: a number whose key names an attribute `group` already has throws
/// InvalidInput instead of overwriting it. LibraryError when HDF5 fails.
void write_record(h5::Group& group, std::string_view method, const RepresentationRecord& record);

/// Reads the record of a representation group: `source` and every float64 scalar attribute (integer and
/// string attributes are structural and skipped). Throws FormatError when `source` is missing.
[[nodiscard]] RepresentationRecord read_record(const h5::Group& group);

/// Throws FormatError "ARCHIVE: <what> 'NAME' has method 'other', expected 'METHOD'" unless the group's
/// `method` attribute is `method` (and the attribute's own FormatError when it is missing).
void check_method(const h5::Group& group, const Archive& archive, const RepresentationKind& kind,
                  const std::string& name, std::string_view method);

/// Opens dataset `item` of a representation group. Throws FormatError "ARCHIVE: <what> 'NAME' has no
/// dataset 'ITEM'" when it is absent or not a dataset.
[[nodiscard]] h5::Dataset open_item(const h5::Group& group, const Archive& archive, const RepresentationKind& kind,
                                    const std::string& name, std::string_view item);

/// Why `item`, which exists, did not open as a dataset: "'ITEM' is damaged (HDF5: CAUSE)" when HDF5 could not
/// read its header (a failed metadata checksum, a bad version number), else "'ITEM' is not a dataset".
[[nodiscard]] std::string dataset_open_failure(std::string_view item, const LibraryError& error);

/// Throws FormatError "ARCHIVE: <what> 'NAME': dataset 'ITEM' has shape (a, b), expected (c, d)" unless
/// `dataset` has shape `expected`.
void check_shape(const h5::Dataset& dataset, const Archive& archive, const RepresentationKind& kind,
                 const std::string& name, std::string_view item, const h5::Dims& expected);

/// The error "ARCHIVE: <what> 'NAME': CAUSE" for a representation whose stored contents are inconsistent.
[[nodiscard]] FormatError representation_error(const Archive& archive, const RepresentationKind& kind,
                                               const std::string& name, std::string_view cause);

/// Reads the sample positions of an adaptively sampled n × n image (dataset `sample_uv` of `g`, float32
/// (n, n, 2)): every value in [0, 1], the boundary samples on their sides of the square, every quad
/// strictly convex (the grid the writers keep; docs/adaptive.md). Throws FormatError naming the item.
[[nodiscard]] std::vector<float> read_sample_uv(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                                                const std::string& name, std::uint64_t n);

/// The region of interest of adaptive image `name` (its group `g`, n × n samples: a geometry image or a
/// flat-octahedron spherical image): `roi_mask`, uint8 flags 0 or 1 (convert --roi); empty when the item has
/// none. Throws FormatError naming the archive, the item and what is wrong (another type or shape, a value
/// above 1).
[[nodiscard]] std::vector<std::uint8_t> read_roi_mask(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                                                      const std::string& name, std::uint64_t n);

}  // namespace gimforge::io
