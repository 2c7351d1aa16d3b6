#include "jobs/cli/option_values.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <system_error>

#include <fmt/format.h>

namespace gimforge::cli {

std::string integer_value_error(std::string_view text, bool is_unsigned) {
  const std::string quoted = fmt::format("'{}'", text);
  std::string_view v = text;
  if (is_unsigned && v.starts_with('-')) return quoted + " is negative";
  if (v.starts_with('-')) v.remove_prefix(1);
  const bool digits = !v.empty() && std::all_of(v.begin(), v.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
  if (!digits || (v.size() > 1 && v.front() == '0')) return quoted + " is not a decimal integer";
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), value);
  const auto limit = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()) + (text.starts_with('-') ? 1u : 0u);
  if (ec != std::errc{} || end != v.data() + v.size() || (!is_unsigned && value > limit)) return quoted + " is out of range";
  return {};
}

namespace {

/// strtod of `text` as CLI11 converts it; nullopt when it is no number; `overflow` when it left double's range.
std::optional<double> as_real(std::string_view text, bool& overflow) {
  const std::string copy(text);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(copy.c_str(), &end);
  overflow = errno == ERANGE && std::isinf(v);
  if (end == copy.c_str() || *end != '\0') return std::nullopt;  // no number, or text after it ("1.5x")
  return v;
}

}  // namespace

std::string real_value_error(std::string_view text) {
  bool overflow = false;
  const std::optional<double> v = as_real(text, overflow);
  if (!v) return fmt::format("'{}' is not a number", text);
  return std::isfinite(*v) && !overflow ? std::string() : std::string("not a finite number");
}

std::string psnr_value_error(std::string_view text) {
  bool overflow = false;
  const std::optional<double> v = as_real(text, overflow);
  if (!v) return "not a number";
  return *v > 0.0 && *v <= 200.0 ? std::string() : std::string("outside (0, 200] dB");
}

std::string name_value_error(std::string_view text) { return text.empty() ? "an empty name names nothing" : ""; }

}  // namespace gimforge::cli
