// Embeds kernels/sphere/domain_tables.bin (the built-in D -> S tables, format in domain_tables.h) into
// gimforge_sphere with the assembler's .incbin: the bytes are part of the library, nothing is read at run
// time. kernels/CMakeLists.txt passes the file's absolute path as GIMFORGE_DOMAIN_TABLES_BIN, makes this
// object depend on the file (OBJECT_DEPENDS) and compiles it without ccache, which cannot see .incbin
// inputs.
#include "kernels/sphere/domain_tables.h"

#ifndef GIMFORGE_DOMAIN_TABLES_BIN
#error "GIMFORGE_DOMAIN_TABLES_BIN (absolute path of kernels/sphere/domain_tables.bin) is not defined"
#endif

asm(".pushsection .rodata\n"
    ".balign 16\n"
    ".globl gimforge_domain_tables_begin\n"
    ".globl gimforge_domain_tables_end\n"
    ".hidden gimforge_domain_tables_begin\n"
    ".hidden gimforge_domain_tables_end\n"
    ".type gimforge_domain_tables_begin, @object\n"
    "gimforge_domain_tables_begin:\n"
    ".incbin \"" GIMFORGE_DOMAIN_TABLES_BIN "\"\n"
    "gimforge_domain_tables_end:\n"
    ".size gimforge_domain_tables_begin, gimforge_domain_tables_end - gimforge_domain_tables_begin\n"
    ".popsection\n");

extern "C" {
[[gnu::visibility("hidden")]] extern const unsigned char gimforge_domain_tables_begin[];
[[gnu::visibility("hidden")]] extern const unsigned char gimforge_domain_tables_end[];
}

namespace gimforge::detail {

std::span<const std::byte> embedded_domain_tables() {
  const auto* begin = reinterpret_cast<const std::byte*>(gimforge_domain_tables_begin);
  const auto* end = reinterpret_cast<const std::byte*>(gimforge_domain_tables_end);
  return {begin, static_cast<std::size_t>(end - begin)};
}

}  // namespace gimforge::detail
