#include "jobs/progress.h"

#include <cstdio>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "jobs/logging.h"

namespace gimforge::jobs {

TerminalProgress::TerminalProgress(std::string label, bool enabled, std::chrono::milliseconds first_line,
                                   std::chrono::milliseconds every)
    : label_(std::move(label)), enabled_(enabled), terminal_(stderr_is_terminal()), first_line_(first_line), every_(every) {}

TerminalProgress::~TerminalProgress() { finish(); }

ProgressCallback TerminalProgress::callback() {
  if (!enabled_) return {};
  return [this](std::string_view stage, double fraction) {
    update(stage, fraction);
    return true;
  };
}

void TerminalProgress::update(std::string_view stage, double fraction) {
  std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  if (!terminal_) {
    if (now - start_ < first_line_ || (logged_ && now - last_ < every_)) return;
    last_ = now;
    logged_ = true;
    spdlog::info("{}: {} {:.0f}% after {:.0f} s", label_, stage, 100.0 * fraction,
                 std::chrono::duration<double>(now - start_).count());
    return;
  }
  if (drawn_ && fraction < 1.0 && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  drawn_ = true;
  std::fputs(fmt::format("\r\033[K{}: {} {:3.0f}%", label_, stage, 100.0 * fraction).c_str(), stderr);
  std::fflush(stderr);
}

void TerminalProgress::finish() {
  std::lock_guard lock(mutex_);
  if (!drawn_) return;
  std::fputs("\r\033[K", stderr);
  std::fflush(stderr);
  drawn_ = false;
}

}  // namespace gimforge::jobs
