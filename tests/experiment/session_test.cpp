#include "avsi/experiment/session.h"

#include <gtest/gtest.h>

namespace avsi::experiment {
namespace {

std::vector<PlannedTrial> small_plan() {
    std::vector<PlannedTrial> plan;
    auto add = [&](Phase phase, int block, const std::string& sentence) {
        PlannedTrial t;
        t.subject = 1;
        t.position = static_cast<int>(plan.size()) + 1;
        t.phase = phase;
        t.block = block;
        t.list = phase == Phase::Test ? std::to_string(block) : to_string(phase);
        t.condition = "c";
        t.sentence = sentence;
        t.stimulus = sentence + "/c.mp4";
        plan.push_back(t);
    };
    add(Phase::Warmup, 0, "w1");
    add(Phase::Practice, 0, "p1");
    add(Phase::Test, 1, "a");
    add(Phase::Test, 1, "b");
    add(Phase::Test, 2, "c");
    return plan;
}

SessionSettings fast() {
    SessionSettings s;
    s.fixation_ms = 100;
    s.response_delay_ms = 0;
    return s;
}

// Runs one trial from Fixation to the answer box; returns the clock.
double present(SessionMachine& m, double t) {
    EXPECT_EQ(m.screen(), Screen::Fixation);
    m.tick(t + 0.05);
    EXPECT_EQ(m.screen(), Screen::Fixation);
    m.tick(t + 0.1);
    EXPECT_EQ(m.screen(), Screen::Stimulus);
    auto actions = m.take_actions();  // may hold the previous trial's commit
    EXPECT_FALSE(actions.empty());
    if (!actions.empty()) {
        EXPECT_EQ(actions.back().kind, SessionAction::Kind::StartStimulus);
    }
    m.stimulus_finished(t + 1.0);
    EXPECT_EQ(m.screen(), Screen::Response);
    return t + 1.0;
}

TEST(Session, WalksThroughPhasesBreaksAndEnd) {
    SessionMachine m(small_plan(), {}, fast());
    EXPECT_EQ(m.screen(), Screen::Instructions);
    EXPECT_FALSE(m.resumed());
    m.continue_pressed(0.0);
    double t = present(m, 0.0);
    m.submit("words", t + 0.5);
    auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::CommitResponse);
    EXPECT_EQ(actions[0].response.text, "words");
    EXPECT_NEAR(actions[0].response.response_time_ms, 500.0, 1e-6);
    // Practice starts with its instructions, then shows the sentence after the answer.
    EXPECT_EQ(m.screen(), Screen::Instructions);
    m.continue_pressed(t);
    t = present(m, t);
    m.submit("x", t);
    EXPECT_EQ(m.screen(), Screen::Feedback);
    m.take_actions();
    m.continue_pressed(t);
    EXPECT_EQ(m.screen(), Screen::Instructions);  // test instructions
    m.continue_pressed(t);
    t = present(m, t);
    m.submit("a", t);
    t = present(m, t);
    m.submit("b", t);
    EXPECT_EQ(m.screen(), Screen::Break);  // block 1 → 2
    m.continue_pressed(t);
    t = present(m, t);
    m.submit("c", t);
    EXPECT_EQ(m.screen(), Screen::End);
    actions = m.take_actions();
    ASSERT_EQ(actions.size(), 2u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::CommitResponse);
    EXPECT_EQ(actions[0].response.text, "c");
    EXPECT_EQ(actions.back().kind, SessionAction::Kind::Finished);
    EXPECT_EQ(m.answered_count(), 5);
}

TEST(Session, EmptyAnswerAsksForConfirmation) {
    SessionMachine m(small_plan(), {}, fast());
    m.continue_pressed(0.0);
    const double t = present(m, 0.0);
    m.take_actions();
    m.submit("   ", t);
    EXPECT_EQ(m.screen(), Screen::ConfirmEmpty);
    EXPECT_TRUE(m.take_actions().empty());
    m.confirm_empty(false, t);
    EXPECT_EQ(m.screen(), Screen::Response);
    m.submit("", t);
    m.confirm_empty(true, t + 2.0);
    const auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_TRUE(actions[0].response.confirmed_empty);
    EXPECT_EQ(actions[0].response.text, "");
    EXPECT_NEAR(actions[0].response.response_time_ms, 2000.0, 1e-6);
}

TEST(Session, ScoreCheckHoldsTheAnswerUntilTheExperimenterAccepts) {
    SessionMachine m(small_plan(), {}, fast());
    m.set_confirm_scores(true);
    m.continue_pressed(0.0);
    const double t = present(m, 0.0);
    m.take_actions();
    m.submit("the boy", t + 1.0);
    EXPECT_EQ(m.screen(), Screen::ScoreCheck);
    EXPECT_TRUE(m.take_actions().empty());
    EXPECT_EQ(m.pending_response().text, "the boy");
    m.escape(t + 2.0);  // a pause keeps the check
    m.escape(t + 3.0);
    EXPECT_EQ(m.screen(), Screen::ScoreCheck);
    m.confirm_score(t + 9.0);
    const auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::CommitResponse);
    EXPECT_EQ(actions[0].response.text, "the boy");
    // The response time ends at Enter in the answer box, not at the check.
    EXPECT_NEAR(actions[0].response.response_time_ms, 1000.0, 1e-6);
    EXPECT_EQ(m.answered_count(), 1);
}

TEST(Session, ResumeSkipsAnsweredTrialsAndPausingAStimulusShowsItAgain) {
    SessionMachine m(small_plan(), {1, 2, 3}, fast());
    EXPECT_TRUE(m.resumed());
    EXPECT_EQ(m.screen(), Screen::Instructions);
    ASSERT_NE(m.trial(), nullptr);
    EXPECT_EQ(m.trial()->position, 4);
    EXPECT_NE(m.message().find("Welcome back"), std::string::npos);
    m.continue_pressed(0.0);
    m.tick(0.2);
    EXPECT_EQ(m.screen(), Screen::Stimulus);
    m.take_actions();
    m.escape(0.3);
    EXPECT_EQ(m.screen(), Screen::Paused);
    auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::StopStimulus);
    m.escape(5.0);
    EXPECT_EQ(m.screen(), Screen::Fixation);
    m.tick(5.1);
    actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::StartStimulus);
    EXPECT_EQ(m.plan()[static_cast<std::size_t>(actions[0].trial_index)].position, 4);
}

TEST(Session, QuitFromPauseEndsWithoutAnswering) {
    SessionMachine m(small_plan(), {}, fast());
    m.quit();  // not paused: ignored
    EXPECT_EQ(m.screen(), Screen::Instructions);
    m.escape(0.0);
    m.quit();
    EXPECT_EQ(m.screen(), Screen::End);
    const auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 1u);
    EXPECT_EQ(actions[0].kind, SessionAction::Kind::Quit);
    EXPECT_EQ(m.answered_count(), 0);
}

TEST(Session, BreakEveryNTrials) {
    SessionSettings s = fast();
    s.break_every = 1;
    std::vector<PlannedTrial> plan = small_plan();
    SessionMachine m(plan, {1, 2}, s);
    m.continue_pressed(0.0);
    const double t = present(m, 0.0);
    m.submit("a", t);
    EXPECT_EQ(m.screen(), Screen::Break);
}

TEST(Session, AllAnsweredStartsAtTheEnd) {
    SessionMachine m(small_plan(), {1, 2, 3, 4, 5}, fast());
    EXPECT_TRUE(m.finished());
}

}  // namespace
}  // namespace avsi::experiment
