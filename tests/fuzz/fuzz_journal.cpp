// Fuzz harness: the batch journal as `gimforge batch --resume` reads it: Journal::replay, then summarize;
// then Journal::open (which cuts a torn last line off) and replay again, which must give the same records
// and no torn line.
#include <cstddef>
#include <cstdint>

#include "io/journal.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = gimforge::fuzz::write_input("journal.jsonl", data, size);
  return gimforge::fuzz::expect_errors([&] {
    std::size_t torn = 0;
    const auto records = gimforge::io::Journal::replay(path, &torn);
    if (torn > 1) __builtin_trap();
    (void)gimforge::io::summarize(records);
    { auto journal = gimforge::io::Journal::open(path); }
    std::size_t torn_after = 0;
    const auto again = gimforge::io::Journal::replay(path, &torn_after);
    if (torn_after != 0 || again != records) __builtin_trap();
  });
}
