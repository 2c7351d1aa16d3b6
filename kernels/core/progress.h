#pragma once
/// \file progress.h
/// Progress and cancellation for long kernels (in the spirit of OpenVDB's interrupter).
#include <functional>
#include <string_view>

#include "kernels/core/errors.h"

namespace gimforge {

/// Called by long-running kernels with a stage name and the fraction of that stage done, in [0, 1].
/// Return false to cancel: the kernel then throws gimforge::Cancelled. An empty function is allowed.
using ProgressCallback = std::function<bool(std::string_view stage, double fraction)>;

/// Reports progress if a callback is set; throws Cancelled when it asks to stop.
inline void report_progress(const ProgressCallback& cb, std::string_view stage, double fraction) {
  if (cb && !cb(stage, fraction)) throw Cancelled(std::string(stage) + ": cancelled");
}

}  // namespace gimforge
