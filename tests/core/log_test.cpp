#include "avsi/core/log.h"

#include <gtest/gtest.h>

#include <thread>

namespace avsi {
namespace {

struct SinkGuard {
    std::shared_ptr<MemorySink> sink = std::make_shared<MemorySink>();
    SinkGuard() { set_log_sink(sink); }
    ~SinkGuard() { set_log_sink(nullptr); }
};

TEST(Log, MessagesReachTheInstalledSink) {
    SinkGuard guard;
    log_info("built {} stimuli", 3);
    log_warning("subject {} dropped", "S07");
    const auto messages = guard.sink->messages();
    ASSERT_EQ(messages.size(), 2u);
    EXPECT_EQ(messages[0].level, LogLevel::Info);
    EXPECT_EQ(messages[0].text, "built 3 stimuli");
    EXPECT_EQ(messages[1].level, LogLevel::Warning);
}

TEST(Log, NoSinkDiscardsSilently) {
    set_log_sink(nullptr);
    EXPECT_NO_THROW(log_info("nobody listens"));
}

TEST(Progress, ReportsStartAndFinishWithCountsFromManyThreads) {
    SinkGuard guard;
    {
        Progress progress("render", 400);
        std::vector<std::thread> threads;
        for (int t = 0; t < 4; ++t)
            threads.emplace_back([&] {
                for (int i = 0; i < 100; ++i) progress.advance();
            });
        for (auto& th : threads) th.join();
    }
    const auto updates = guard.sink->updates();
    ASSERT_GE(updates.size(), 2u);
    EXPECT_EQ(updates.front().done, 0u);
    EXPECT_FALSE(updates.front().finished);
    EXPECT_TRUE(updates.back().finished);
    EXPECT_EQ(updates.back().done, 400u);
    EXPECT_EQ(updates.back().total, 400u);
}

TEST(ProgressUpdate, EtaFromRate) {
    ProgressUpdate u{"x", 25, 100, 10.0, false};
    EXPECT_DOUBLE_EQ(u.eta_s(), 30.0);
    u.done = 0;
    EXPECT_LT(u.eta_s(), 0.0);
}

}  // namespace
}  // namespace avsi
