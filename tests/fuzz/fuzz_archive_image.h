#pragma once
/// \file fuzz_archive_image.h
/// Opens fuzz input as a gimforge archive without touching the disk: the bytes become an HDF5 file image
/// (H5Pset_file_image) on the core driver without backing store, and io::Archive::open goes through the
/// same checks as for a file. Two quirks of the layers below decide the name passed: h5::File::open
/// requires that the path exists, and HDF5's core driver refuses to open an image under a name it can
/// open(2) ("file already exists"). A Unix socket node satisfies both: it exists, and open(2) fails on it.
#include <hdf5.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

#include "io/archive.h"
#include "io/representation.h"
#include "tests/fuzz/fuzz_support.h"

namespace gimforge::fuzz {

/// The name under which file images are opened: a socket node in scratch_dir().
inline const std::filesystem::path& image_name() {
  static const std::filesystem::path path = [] {
    std::filesystem::path p = scratch_dir() / "image.h5";
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string s = p.string();
    if (s.size() >= sizeof addr.sun_path) std::abort();
    std::memcpy(addr.sun_path, s.c_str(), s.size() + 1);
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    if (fd < 0 || ::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) std::abort();
    ::close(fd);
    return p;
  }();
  return path;
}

/// File access properties that present `size` bytes at `data` as the file (HDF5 copies them).
inline h5::FileAccess file_image(const std::uint8_t* data, std::size_t size) {
  h5::FileAccess access;
  access.add("core driver", [](h5::Hid plist) { return H5Pset_fapl_core(plist, 1 << 16, 0); });
  access.add("file image", [&](h5::Hid plist) {
    return H5Pset_file_image(plist, const_cast<std::uint8_t*>(data), size);
  });
  return access;
}

/// The input opened as an archive (read-only). Throws what io::Archive::open throws.
inline io::Archive open_image(const std::uint8_t* data, std::size_t size) {
  if (size == 0) throw IoError("empty input");
  return io::Archive::open(image_name(), h5::OpenMode::kReadOnly, file_image(data, size));
}

/// The region of interest of an adaptive n × n image (preview's <name>_roi.png) as read_roi_mask gives it:
/// none, or n² flags of 0 or 1 (a trap otherwise).
inline void check_roi_mask(const io::Archive& archive, const io::RepresentationKind& kind, const std::string& name,
                           std::uint64_t n) {
  const std::vector<std::uint8_t> roi =
      io::read_roi_mask(io::open_representation(archive, kind, name), archive, kind, name, n);
  if (!roi.empty() && roi.size() != n * n) __builtin_trap();
  for (const std::uint8_t v : roi)
    if (v > 1) __builtin_trap();
}

}  // namespace gimforge::fuzz
