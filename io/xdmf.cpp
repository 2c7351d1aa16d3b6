#include "io/xdmf.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <optional>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/batch_archive.h"
#include "io/hdf5.h"
#include "io/hdf5_storage.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

std::string xml_escape(std::string_view text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        // Control characters are not allowed in XML 1.0 at all: write them as a visible '?'.
        out += (static_cast<unsigned char>(c) < 0x20 && c != '\t') ? '?' : c;
    }
  }
  return out;
}

std::string dims_text(const h5::Dims& dims) {
  std::string out;
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (i > 0) out += ' ';
    out += std::to_string(dims[i]);
  }
  return out;
}

/// "Float" precision 4 for float32, "UChar" precision 1 for uint8: the dtypes the images are stored as.
std::optional<std::string> number_type(h5::DType type) {
  if (type == h5::DType::kFloat32) return R"(NumberType="Float" Precision="4")";
  if (type == h5::DType::kUInt8) return R"(NumberType="UChar" Precision="1")";
  return std::nullopt;
}

struct Writer {
  std::string h5;  ///< the archive's reference name
  std::string xml;

  std::string hdf_item(const h5::Dataset& ds, const h5::Dims& dims, const std::string& type) const {
    return fmt::format(R"(<DataItem Dimensions="{}" {} Format="HDF">{}:{}</DataItem>)", dims_text(dims), type,
                       xml_escape(h5), xml_escape(ds.path()));
  }

  /// A hyperslab of `ds` starting at `start` with extents `count` (stride 1).
  std::string slab(const h5::Dataset& ds, const h5::Dims& start, const h5::Dims& count, const std::string& type) const {
    const h5::Dims dims = ds.shape();
    h5::Dims ones(dims.size(), 1);
    return fmt::format(
        R"(<DataItem ItemType="HyperSlab" Dimensions="{}" Type="HyperSlab"><DataItem Dimensions="3 {}" Format="XML">{} {} {}</DataItem>{}</DataItem>)",
        dims_text(count), dims.size(), dims_text(start), dims_text(ones), dims_text(count), hdf_item(ds, dims, type));
  }

  void open_grid(const std::string& name, std::uint64_t rows, std::uint64_t cols, const std::string& indent) {
    xml += fmt::format("{}<Grid Name=\"{}\" GridType=\"Uniform\">\n", indent, xml_escape(name));
    xml += fmt::format("{}  <Topology TopologyType=\"2DSMesh\" Dimensions=\"{} {}\"/>\n", indent, rows, cols);
  }

  /// A (H, W, 3) image (or rows [row0, row0 + rows) of one) as a grid of points, with optional node
  /// attributes of the same layout.
  void image_grid(const std::string& name, const h5::Dataset& geometry, std::uint64_t row0, std::uint64_t rows,
                  const std::vector<std::pair<std::string, h5::Dataset>>& attributes) {
    const h5::Dims dims = geometry.shape();
    const std::uint64_t cols = dims[1];
    open_grid(name, rows, cols, "    ");
    const bool whole = row0 == 0 && rows == dims[0];
    const std::string f32 = *number_type(h5::DType::kFloat32);
    xml += "      <Geometry GeometryType=\"XYZ\">";
    xml += whole ? hdf_item(geometry, dims, f32) : slab(geometry, {row0, 0, 0}, {rows, cols, 3}, f32);
    xml += "</Geometry>\n";
    for (const auto& [label, ds] : attributes) {
      const h5::Dims a = ds.shape();
      const std::optional<std::string> type = number_type(ds.dtype());
      if (!type || a.size() < 2 || a[0] != dims[0] || a[1] != cols) continue;
      const bool vector = a.size() == 3 && a[2] == 3;
      if (!vector && a.size() != 2) continue;
      h5::Dims start{row0, 0}, count{rows, cols};
      if (vector) start.push_back(0), count.push_back(3);
      xml += fmt::format("      <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"Node\">", label,
                         vector ? "Vector" : "Scalar");
      xml += whole ? hdf_item(ds, a, *type) : slab(ds, start, count, *type);
      xml += "</Attribute>\n";
    }
    xml += "    </Grid>\n";
  }

  void geometry_image(const h5::Group& group, const std::string& label) {
    if (!group.exists("geometry")) return;
    const h5::Dataset geometry = group.open_dataset("geometry");
    const h5::Dims dims = geometry.shape();
    if (dims.size() != 3 || dims[2] != 3 || geometry.dtype() != h5::DType::kFloat32) return;
    std::vector<std::pair<std::string, h5::Dataset>> attributes;
    if (group.exists("colors")) attributes.emplace_back("color", group.open_dataset("colors"));
    image_grid(label, geometry, 0, dims[0], attributes);
  }

  void spherical_image(const h5::Group& group, const std::string& label) {
    if (!group.exists("geometry")) return;
    const h5::Dataset geometry = group.open_dataset("geometry");
    const h5::Dims dims = geometry.shape();
    if (dims.size() != 3 || dims[2] != 3 || geometry.dtype() != h5::DType::kFloat32) return;
    std::int64_t faces = 1;
    if (geometry.has_attribute("faces")) faces = geometry.attribute<std::int64_t>("faces");
    if (faces < 1 || faces > 64 || dims[0] % static_cast<std::uint64_t>(faces) != 0) return;
    std::vector<std::pair<std::string, h5::Dataset>> attributes;
    if (group.exists("mask")) attributes.emplace_back("mask", group.open_dataset("mask"));
    if (group.exists("colors")) attributes.emplace_back("color", group.open_dataset("colors"));
    const std::uint64_t height = dims[0] / static_cast<std::uint64_t>(faces);
    if (faces == 1) {
      image_grid(label, geometry, 0, dims[0], attributes);
      return;
    }
    for (std::uint64_t f = 0; f < static_cast<std::uint64_t>(faces); ++f)
      image_grid(fmt::format("{} face {}", label, f), geometry, f * height, height, attributes);
  }

  /// A batch stack (N, 3, H, W): a temporal collection, item k a hyperslab per coordinate plane, named by `names`
  /// (read_batch_output's, checked: one per item).
  void batch_stack(const h5::Group& group, const std::string& label, const std::vector<std::string>& names) {
    if (!group.exists("data")) return;
    const h5::Dataset data = group.open_dataset("data");
    const h5::Dims d = data.shape();
    if (d.size() != 4 || d[1] != 3 || d[0] == 0 || data.dtype() != h5::DType::kFloat32) return;
    std::optional<h5::Dataset> mask;
    if (group.exists("mask")) {
      h5::Dataset m = group.open_dataset("mask");
      const h5::Dims md = m.shape();
      if (md.size() == 4 && md[0] == d[0] && md[1] == 1 && md[2] == d[2] && md[3] == d[3] &&
          m.dtype() == h5::DType::kUInt8)
        mask = std::move(m);
    }
    // A cube-domain stack holds six face images one above the other: one grid per face, as for /spherical.
    const bool cube = group.has_attribute("domain") && group.attribute<std::string>("domain") == "cube";
    const std::uint64_t faces = cube && d[2] % 6 == 0 ? 6 : 1;
    const std::uint64_t rows = d[2] / faces;
    const std::string f32 = *number_type(h5::DType::kFloat32);
    xml += fmt::format("    <Grid Name=\"{}\" GridType=\"Collection\" CollectionType=\"Temporal\">\n", xml_escape(label));
    for (std::uint64_t k = 0; k < d[0]; ++k) {
      const std::string item = k < names.size() ? names[k] : std::to_string(k);
      if (faces > 1)
        xml += fmt::format("      <Grid Name=\"{} {}\" GridType=\"Collection\" CollectionType=\"Spatial\">\n",
                           xml_escape(label), xml_escape(item));
      for (std::uint64_t f = 0; f < faces; ++f) {
        const std::string grid = faces > 1 ? fmt::format("{} {} face {}", label, item, f) : fmt::format("{} {}", label, item);
        open_grid(grid, rows, d[3], "      ");
        xml += fmt::format("        <Time Value=\"{}\"/>\n", k);
        xml += "        <Geometry GeometryType=\"X_Y_Z\">";
        for (std::uint64_t c = 0; c < 3; ++c) xml += slab(data, {k, c, f * rows, 0}, {1, 1, rows, d[3]}, f32);
        xml += "</Geometry>\n";
        if (mask) {
          xml += R"(        <Attribute Name="mask" AttributeType="Scalar" Center="Node">)";
          xml += slab(*mask, {k, 0, f * rows, 0}, {1, 1, rows, d[3]}, *number_type(h5::DType::kUInt8));
          xml += "</Attribute>\n";
        }
        xml += "      </Grid>\n";
      }
      if (faces > 1) xml += "      </Grid>\n";
    }
    xml += "    </Grid>\n";
  }
};

/// Calls fn(item group, "GROUP/NAME") for each item of /GROUP that is not in `leave_out` and whose datasets
/// the file stores whole (a viewer would draw fill values where a chunk was never written).
template <class Fn>
void for_each_child(const h5::File& root, std::string_view group_name, std::span<const std::string> leave_out, Fn&& fn) {
  if (!root.exists(group_name)) return;
  const h5::Group group = root.open_group(group_name);
  for (const std::string& name : group.children()) {
    const std::string label = std::string(group_name) + "/" + name;
    if (std::ranges::find(leave_out, label) != leave_out.end()) continue;
    try {
      const h5::Group item = group.open_group(name);
      h5::require_stored(item, group_name == "batch" ? "items" : "");  // item groups: not described
      fn(item, label);
    } catch (const Error&) {
      // Not a group, or damaged: not renderable. `gimforge ls` and the readers say why.
    }
  }
}

}  // namespace

std::string archive_xdmf(const Archive& archive, const std::string& h5_reference, std::span<const std::string> leave_out) {
  Writer w{.h5 = h5_reference, .xml = {}};
  w.xml = "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
          "<Xdmf Version=\"3.0\">\n  <Domain>\n";
  const h5::File& root = archive.root();
  for_each_child(root, "gim", leave_out, [&](const h5::Group& g, const std::string& label) { w.geometry_image(g, label); });
  for_each_child(root, "spherical", leave_out, [&](const h5::Group& g, const std::string& label) { w.spherical_image(g, label); });
  // Only an output the readers accept (its 'data' holds `count` items): the stack's extent sizes the XML.
  for_each_child(root, "batch", leave_out, [&](const h5::Group& g, const std::string& label) {
    w.batch_stack(g, label, read_batch_output(archive, label.substr(label.find('/') + 1)).names);
  });
  w.xml += "  </Domain>\n</Xdmf>\n";
  return w.xml;
}

std::filesystem::path xdmf_sidecar_path(const std::filesystem::path& archive) {
  std::filesystem::path out = archive;
  std::string extension = archive.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".xmf")  // any case: case-insensitive file systems
    out += ".xmf";  // an archive named *.xmf: its sidecar must not replace it
  else
    out.replace_extension(".xmf");
  return out;
}

std::filesystem::path write_xdmf_sidecar(const std::filesystem::path& archive_path, bool* grids,
                                         std::span<const std::string> leave_out) {
  const std::string xml = [&] {
    const Archive archive = Archive::open(archive_path);
    return archive_xdmf(archive, archive_path.filename().string(), leave_out);
  }();
  if (grids != nullptr) *grids = xml.find("<Grid ") != std::string::npos;
  const std::filesystem::path sidecar = xdmf_sidecar_path(archive_path);
  write_atomically(
      sidecar,
      [&](const std::filesystem::path& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out << xml;
        out.close();
        if (!out) throw IoError(tmp.string() + ": cannot write");
      },
      ParentDirectory::kMustExist);
  return sidecar;
}

}  // namespace gimforge::io
