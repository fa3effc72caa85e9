// One progress and cancel shape for the library (flowvid/progress.hpp).

#include "flowvid/progress.hpp"

#include <gtest/gtest.h>

#include <vector>

TEST(Progress, AFalseAnswerCancelsAndAMessageNeverDoes) {
    std::vector<flowvid::ProgressReport> heard;
    bool go_on = true;
    const flowvid::Progress progress = [&](const flowvid::ProgressReport& report) {
        heard.push_back(report);
        return go_on;
    };
    flowvid::report_progress(progress, "render", 0.25);
    go_on = false;
    flowvid::report_message(progress, "prepare", "background: median");  // a log line is not a checkpoint
    EXPECT_THROW(flowvid::report_progress(progress, "render", 0.5), flowvid::Cancelled);
    ASSERT_EQ(heard.size(), 3u);
    EXPECT_EQ(heard[0].stage, "render");
    EXPECT_DOUBLE_EQ(heard[0].fraction, 0.25);
    EXPECT_TRUE(heard[0].message.empty());
    EXPECT_LT(heard[1].fraction, 0.0);  // a message carries no fraction
    EXPECT_EQ(heard[1].message, "background: median");
    EXPECT_DOUBLE_EQ(heard[2].fraction, 0.5);
    // No callback: nothing reported, nothing cancelled.
    EXPECT_NO_THROW(flowvid::report_progress({}, "render", 1.0));
    EXPECT_NO_THROW(flowvid::report_message({}, "render", "x"));
}
