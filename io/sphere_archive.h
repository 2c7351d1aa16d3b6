#pragma once
/// \file sphere_archive.h
/// Spherical geometry images in the gimforge archive (docs/archive.md, "Spherical geometry images";
/// Praun & Hoppe 2003). With S = faces·height samples rows of the domain's image layout (DomainImage):
///   /spherical/<name>/geometry                float32 (S, width, 3)  positions, NaN where undefined
///   /spherical/<name>/mask                    uint8 (S, width)       1 defined, 0 in a filled hole
///   /spherical/<name>/colors                  float32 (S, width, 3)  colours resampled (when the input had them)
///   /spherical/<name>/sample_uv               float32 (S, width, 2)  adaptive sampling (flat-octa): each
///                                                                    sample's point of the image's square
///   /spherical/<name>/parametrization/sphere  float64 (V, 3)         unit vector of every vertex of the
///                                                                    closed mesh that was parametrized
/// with attributes on /spherical/<name>: method "sphere", domain, n, source, and the record's numbers
/// (fidelity, stretch efficiencies, hole statistics, timings).
#include <cstddef>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/core/mesh.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::io {

/// Where spherical geometry images live in the archive (/spherical/<name>) and what messages call them.
inline constexpr RepresentationKind kSphericalImages{"spherical", "spherical geometry image"};

/// Scalar facts stored as attributes of /spherical/<name> next to the images (e.g. "psnr",
/// "map_efficiency", "domain_efficiency", "efficiency_domain_to_mesh", "holes_filled", "seconds_total").
using SphereRecord = RepresentationRecord;

/// The spherical parametrization S → M a spherical geometry image was sampled from, so that other domains
/// or sizes can be resampled later without re-optimizing (resample_spherical_image).
struct SphereParametrization {
  /// One unit vector per vertex of the closed mesh that was parametrized: the input mesh's vertices first
  /// (same order), then one centre vertex per filled hole (SphereResult::sphere).
  std::vector<Vec3> sphere;
  std::size_t input_vertices{0};  ///< vertices of the (repaired) input mesh; sphere.size() − input_vertices holes
  std::size_t input_faces{0};     ///< faces of the (repaired) input mesh
};

/// Writes spherical geometry image `name` (a new group /spherical/<name>) with its mask, colours (when
/// image.colors is not empty), parametrization and record. Throws InvalidInput for an invalid name, for
/// arrays whose sizes do not match image.layout(), for a mask entry other than 0/1 or a mask that
/// disagrees with the positions (NaN exactly where it is 0), for a parametrization with fewer unit vectors
/// than input vertices or a row that is not a unit vector, or for a record number that collides with a
/// structural attribute, before anything is written; LibraryError if the group exists or HDF5 fails. An empty
/// parametrization (no vectors, input_vertices 0: a decompressed item) is not written.
void write_spherical_image(Archive& archive, const std::string& name, const SphericalImage& image,
                           const SphereParametrization& parametrization, const SphereRecord& record);

/// Writes the layout attributes `domain` and `n` on `object`, and with `image_sizes` also `faces`, `width`
/// and `height` (those of the `geometry` dataset): for compressed items (jobs/compress.h).
void write_sphere_layout(h5::Object& object, const DomainImage& layout, bool image_sizes);

/// Throws InvalidInput "spherical geometry image 'NAME': CAUSE" unless the arrays of `image` fit
/// image.layout(), the mask holds only 0 and 1, and the positions are finite exactly where it is 1 (NaN where
/// 0): what the readers and writers check.
void check_spherical_image(const std::string& name, const SphericalImage& image);

/// The stored shape (S, W, channels) of an image of `layout` ((S, W) when channels is 0).
[[nodiscard]] h5::Dims sphere_image_shape(const DomainImage& layout, std::uint64_t channels);

/// Reads spherical geometry image `name` (positions float32, quantized or coded: io/coded_image.h): domain and n from the attributes, positions, mask and (when
/// stored) colours. Checks the method, the domain name, n, every shape against the domain's layout, that
/// the mask holds only 0 and 1, and that masked samples are NaN and the others finite. Throws InvalidInput
/// for an invalid name and FormatError naming the archive, the image and the missing or inconsistent item.
[[nodiscard]] SphericalImage read_spherical_image(const Archive& archive, const std::string& name);

/// The same for a group laid out like /spherical/<name> elsewhere in the archive (a compressed batch item);
/// `name` labels the messages.
[[nodiscard]] SphericalImage read_spherical_image(const Archive& archive, const h5::Group& group, const std::string& name);

/// Reads the record (attributes) of spherical geometry image `name`. Throws FormatError when it is absent.
[[nodiscard]] SphereRecord read_spherical_record(const Archive& archive, const std::string& name);

/// Reads the parametrization of spherical geometry image `name`. Checks the (V, 3) shape, that V is at
/// least input_vertices and that every row is a unit vector. Throws FormatError naming the item otherwise.
[[nodiscard]] SphereParametrization read_sphere_parametrization(const Archive& archive, const std::string& name);

/// Names of the spherical geometry images in the archive (children of /spherical), sorted.
[[nodiscard]] std::vector<std::string> spherical_image_names(const Archive& archive);

}  // namespace gimforge::io
