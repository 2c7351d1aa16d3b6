// Names from archives, job files and file names are printed through io::printable(): terminal escapes
// and newlines must not reach the terminal or forge log lines (issue: terminal and log injection).
#include "io/printable.h"

#include <gtest/gtest.h>

namespace gimforge::io {
namespace {

TEST(Printable, KeepsOrdinaryAndUtf8Text) {
  EXPECT_EQ(printable("bunny_01.ply"), "bunny_01.ply");
  EXPECT_EQ(printable("caf\xc3\xa9 \xe6\x97\xa5\xe6\x9c\xac \xf0\x9f\x90\x87"), "caf\xc3\xa9 \xe6\x97\xa5\xe6\x9c\xac \xf0\x9f\x90\x87");
  EXPECT_FALSE(has_unprintable("caf\xc3\xa9"));
}

TEST(Printable, EscapesControlCharactersSoNoLineCanBeForged) {
  const std::string forged = "x\ngimforge: info: all 10 items done\x1b[2J\r\t\x7f";
  const std::string shown = printable(forged);
  EXPECT_EQ(shown, "x\\ngimforge: info: all 10 items done\\e[2J\\r\\t\\x7f");
  EXPECT_EQ(shown.find('\n'), std::string::npos);
  EXPECT_EQ(shown.find('\x1b'), std::string::npos);
  EXPECT_TRUE(has_unprintable(forged));
  EXPECT_EQ(printable(shown), shown) << "idempotent on its own output";
  EXPECT_EQ(printable(std::string_view("a\0b", 3)), "a\\x00b");
}

TEST(Printable, EscapesC1ControlsAndInvalidUtf8) {
  EXPECT_EQ(printable("\xc2\x9b" "31m"), "\\u009b31m");   // C1 CSI, read as ESC [ by some terminals
  EXPECT_EQ(printable("\xff\xfe"), "\\xff\\xfe");         // not UTF-8
  EXPECT_EQ(printable("\xc0\xaf"), "\\xc0\\xaf");         // overlong '/'
  EXPECT_EQ(printable("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // surrogate
  EXPECT_EQ(printable("\xe6\x97"), "\\xe6\\x97");         // truncated sequence
  EXPECT_TRUE(has_unprintable("\xc2\x85"));
}

TEST(Printable, PathComponentsRefuseTraversalAndControls) {
  EXPECT_EQ(path_component_problem("chair_0001"), "");
  EXPECT_EQ(path_component_problem("caf\xc3\xa9"), "");
  EXPECT_NE(path_component_problem(""), "");
  EXPECT_NE(path_component_problem("."), "");
  EXPECT_NE(path_component_problem(".."), "");
  EXPECT_NE(path_component_problem("a/b"), "");
  EXPECT_NE(path_component_problem("../../etc/passwd"), "");
  EXPECT_NE(path_component_problem("x\ny"), "");
  EXPECT_EQ(path_component_problem(std::string(255, 'x')), "");
  EXPECT_EQ(path_component_problem(std::string(256, 'x')), "is 256 bytes long (a file name holds at most 255)");
  EXPECT_NE(path_component_problem(std::string_view("x\0y", 3)), "");
}

}  // namespace
}  // namespace gimforge::io
