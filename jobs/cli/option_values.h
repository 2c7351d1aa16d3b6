#pragma once
/// \file option_values.h
/// What option values must look like beyond CLI11's own conversions (internal to the executable; cli.cpp
/// attaches these to the options). Each returns "" for a good value, else the reason CLI11 prints.
#include <functional>
#include <string>
#include <string_view>

namespace gimforge::jobs {
struct MethodOptions;
}

namespace gimforge::cli {

/// Integer options are plain decimal (CLI11 reads base 0: "010" was 8; no "+"), an unsigned one takes no sign, and a
/// value must fit 64 bits (CLI11 saturates: --rate 10^23 became 2^64 − 1).
[[nodiscard]] std::string integer_value_error(std::string_view text, bool is_unsigned);

/// Real options are finite: CLI11 converts with strtod and its ranges let "nan" through; "inf" and what
/// overflows to it (1e400) are refused too. Text that is no number at all is left to CLI11, which names it.
[[nodiscard]] std::string real_value_error(std::string_view text);

/// compress --psnr: a finite target in (0, 200] dB.
[[nodiscard]] std::string psnr_value_error(std::string_view text);

/// A --name given empty names nothing (compress --name "" compressed every item).
[[nodiscard]] std::string name_value_error(std::string_view text);

/// batch --label: a fixed label goes into item names, archives and log lines, so it holds no control character
/// or invalid UTF-8 (it was exit 1 after the options were read, not a usage error).
[[nodiscard]] std::string label_value_error(std::string_view text);

/// An option given where it does not apply: its name and why ("" when none).
struct OptionProblem {
  std::string option;
  std::string reason;
};

/// The first option of one conversion method given with another (--size with --method relief), or of
/// --sampling adaptive with uniform sampling, ...; `given(name)` says whether the command line holds it.
[[nodiscard]] OptionProblem method_option_problem(const jobs::MethodOptions& o,
                                                  const std::function<bool(const char*)>& given);

}  // namespace gimforge::cli
