#include "jobs/cli/option_values.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "io/printable.h"
#include "jobs/method.h"

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

std::string label_value_error(std::string_view text) {
  return io::has_unprintable(text) ? fmt::format("'{}' contains a control character or invalid UTF-8", io::printable(text))
                                   : std::string();
}

OptionProblem method_option_problem(const jobs::MethodOptions& o, const std::function<bool(const char*)>& given) {
  const auto only = [&](std::initializer_list<const char*> names, jobs::Method method) -> OptionProblem {
    for (const char* name : names)
      if (o.method != method && given(name))
        return {name, fmt::format("applies to --method {} only (this is --method {})", jobs::method_name(method),
                                  jobs::method_name(o.method))};
    return {};
  };
  for (OptionProblem p : {only({"--domain", "--n", "--sphere-map"}, jobs::Method::Sphere),
                          only({"--size", "--normal-size", "--max-augmentations"}, jobs::Method::Gim),
                          only({"--grid", "--texture", "--max-grid", "--occlusion-threshold"}, jobs::Method::Relief),
                          only({"--samples", "--charts"}, jobs::Method::Mcgim)})
    if (!p.option.empty()) return p;
  for (const char* name : {"--sampling", "--adapt-rounds", "--adapt-start", "--roi", "--roi-gain"})
    if (given(name) && o.method != jobs::Method::Gim && o.method != jobs::Method::Sphere)
      return {name, fmt::format("applies to --method gim and sphere only (this is --method {})", jobs::method_name(o.method))};
  for (const char* name : {"--adapt-rounds", "--adapt-start", "--roi", "--roi-gain"})
    if (given(name) && !o.adaptive()) return {name, "applies to --sampling adaptive only (this is --sampling uniform)"};
  if (given("--roi-gain") && o.roi.empty())
    return {"--roi-gain", "applies with --roi only (the samples the region of interest gets)"};
  for (const char* name : {"--proxy-faces", "--proxy-bricks", "--wrap", "--optimize"})
    if (given(name) && o.method == jobs::Method::Relief)
      return {name, "applies to the image methods gim, sphere and mcgim only (this is --method relief)"};
  if (o.grid != "auto")
    for (const char* name : {"--max-grid", "--occlusion-threshold"})
      if (given(name)) return {name, fmt::format("applies to --grid auto only (this is --grid {})", o.grid)};
  return {};
}

}  // namespace gimforge::cli
