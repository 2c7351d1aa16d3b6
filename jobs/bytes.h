#pragma once
/// \file bytes.h
/// A byte buffer written and read in order: vectors of trivially copyable elements, each as a u64 count and
/// its elements in this machine's byte order. What ranks send each other (jobs/brick_convert.cpp) and what
/// a batch's brick tasks leave in its work directory (jobs/brick_tasks.h), both read back by the same build.
/// Reading past the end throws FormatError naming `what`.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::jobs {

struct Bytes {
  std::vector<std::byte> data;
  std::size_t at{0};
  std::string what{"a message between ranks"};  ///< named by the errors of reading

  template <class T>
  void put(const std::vector<T>& v) {
    const std::uint64_t n = v.size();
    put_raw(&n, sizeof n);
    put_raw(v.data(), v.size() * sizeof(T));
  }
  void put_raw(const void* p, std::size_t bytes) {
    const auto* b = static_cast<const std::byte*>(p);
    data.insert(data.end(), b, b + bytes);
  }
  template <class T>
  [[nodiscard]] std::vector<T> get() {
    std::uint64_t n = 0;
    get_raw(&n, sizeof n);
    if (n > (data.size() - at) / sizeof(T)) short_of("its contents");
    std::vector<T> v(static_cast<std::size_t>(n));
    get_raw(v.data(), v.size() * sizeof(T));
    return v;
  }
  void get_raw(void* p, std::size_t bytes) {
    if (bytes > data.size() - at) short_of("its contents");
    if (bytes > 0) std::memcpy(p, data.data() + at, bytes);
    at += bytes;
  }
  [[noreturn]] void short_of(const char* part) const {
    throw FormatError(fmt::format("{} is shorter than {}", what, part));
  }
};

}  // namespace gimforge::jobs
