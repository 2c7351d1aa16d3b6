#pragma once
/// \file agree.h
/// Failing together: a rank whose local work throws must not leave the others waiting in the next
/// collective (huge-scans notes, "Failure behaviour"). run_agreed runs the local part on every rank and then
/// agrees with an allreduce whether any rank failed; if so every rank throws, and only one of them with the
/// real error, so a job prints one line for one cause.
#include <functional>

#include "kernels/core/errors.h"
#include "mpi/comm.h"

namespace gimforge::mpi {

/// Thrown on the ranks that did not fail themselves when another rank did: the caller exits with an error
/// without printing (the failing rank prints).
class PeerFailed : public Error {
 public:
  using Error::Error;
};

/// Runs `local` on this rank, then (collective) agrees on failure: when no rank threw, returns; otherwise
/// the lowest failing rank rethrows its exception and every other rank throws PeerFailed. Exceptions that
/// are not gimforge::Error (bad_alloc, std::exception) count as failures too.
void run_agreed(const Comm& comm, const std::function<void()>& local);

}  // namespace gimforge::mpi
