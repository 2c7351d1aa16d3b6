// Progress of long work where stderr is not a terminal (a log file, a Slurm job): a log line now and then
// (jobs/progress.h), nothing for quick work.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <sstream>
#include <string>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "jobs/logging.h"
#include "jobs/progress.h"

namespace gimforge::jobs {
namespace {

/// Collects what the default logger writes while it lives.
class CapturedLog {
 public:
  CapturedLog() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(text_)) {
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~CapturedLog() {
    auto& sinks = spdlog::default_logger()->sinks();
    std::erase(sinks, sink_);
  }
  [[nodiscard]] std::string text() const { return text_.str(); }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

TEST(Progress, WithoutATerminalLongWorkLogsALineNowAndThen) {
  set_stderr_is_terminal(false);
  spdlog::set_level(spdlog::level::info);
  {
    const CapturedLog log;
    TerminalProgress quick("convert", true);  // the first line only after 10 s
    const ProgressCallback cb = quick.callback();
    ASSERT_TRUE(cb);
    for (int i = 0; i <= 10; ++i) cb("pack", i / 10.0);
    EXPECT_EQ(log.text(), "");
  }
  {
    const CapturedLog log;
    TerminalProgress slow("convert", true, std::chrono::milliseconds(0), std::chrono::hours(1));
    const ProgressCallback cb = slow.callback();
    cb("pack", 0.25);
    cb("pack", 0.5);  // within the interval: no second line
    EXPECT_NE(log.text().find("convert: pack 25% after 0 s"), std::string::npos) << log.text();
    EXPECT_EQ(log.text().find("50%"), std::string::npos) << log.text();
  }
  {
    const CapturedLog log;
    TerminalProgress off("convert", false, std::chrono::milliseconds(0), std::chrono::milliseconds(0));
    EXPECT_FALSE(off.callback());
  }
}

}  // namespace
}  // namespace gimforge::jobs
