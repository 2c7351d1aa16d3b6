#pragma once
/// \file errors.h
/// The gimforge exception hierarchy. Every public function documents which of these it throws.
/// Messages are one line and name the offending item (a file, a face index, a parameter) and the cause,
/// so the CLI can print `gimforge: error: <message>` and a batch can record the reason per item.
#include <stdexcept>
#include <string>

namespace gimforge {

/// Base of every error gimforge throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The data handed in is unusable: a mesh with out-of-range indices or NaN coordinates, an option out of
/// its range, a mesh whose topology the algorithm does not accept.
class InvalidInput : public Error {
 public:
  using Error::Error;
};

/// The mesh's topology does not suit the requested algorithm (non-manifold, several components, wrong genus).
class TopologyError : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// A file could not be opened, read, parsed or written. The message starts with the path.
class IoError : public Error {
 public:
  using Error::Error;
};

/// A file's contents are not what its format promises (truncated, corrupt, wrong magic).
class FormatError : public IoError {
 public:
  using IoError::IoError;
};

/// A third-party library (Embree, HDF5, MPI) reported a failure.
class LibraryError : public Error {
 public:
  using Error::Error;
};

/// A numerical procedure failed (did not converge, produced a non-finite value).
class NumericalError : public Error {
 public:
  using Error::Error;
};

/// Work was cancelled through a progress callback.
class Cancelled : public Error {
 public:
  using Error::Error;
};

}  // namespace gimforge
