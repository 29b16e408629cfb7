// The session state machine (see session.h).
#include "avsi/experiment/session.h"

#include <algorithm>
#include <cctype>

#include "avsi/core/error.h"

namespace avsi::experiment {

namespace {
// Clock sums (t + 0.1 − t) can land a few ulps short of a duration.
constexpr double time_slack_ms = 1e-6;

bool blank(const std::string& s) {
    return std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isspace(c) != 0; });
}
}  // namespace

std::string to_string(Screen screen) {
    switch (screen) {
        case Screen::Instructions: return "instructions";
        case Screen::Fixation: return "fixation";
        case Screen::Stimulus: return "trial";
        case Screen::Wait: return "wait";
        case Screen::Response: return "response";
        case Screen::ConfirmEmpty: return "confirm-empty";
        case Screen::ScoreCheck: return "score-check";
        case Screen::Feedback: return "feedback";
        case Screen::Break: return "break";
        case Screen::Paused: return "paused";
        case Screen::End: return "end";
    }
    return "?";
}

SessionMachine::SessionMachine(std::vector<PlannedTrial> plan, const std::vector<int>& answered,
                               SessionSettings settings)
    : m_plan(std::move(plan)), m_answered(m_plan.size(), false), m_settings(std::move(settings)) {
    for (int position : answered)
        for (std::size_t i = 0; i < m_plan.size(); ++i)
            if (m_plan[i].position == position && !m_answered[i]) {
                m_answered[i] = true;
                ++m_answered_count;
            }
    m_resumed = m_answered_count > 0;
    go_to_next(0.0, true);
}

const PlannedTrial* SessionMachine::trial() const {
    if (m_current < 0 || m_current >= static_cast<int>(m_plan.size())) return nullptr;
    return &m_plan[static_cast<std::size_t>(m_current)];
}

void SessionMachine::go_to_next(double now_s, bool first) {
    const int previous = m_current;
    int next = m_current + 1;
    while (next < static_cast<int>(m_plan.size()) && m_answered[static_cast<std::size_t>(next)]) ++next;
    m_state_start_s = now_s;
    if (next >= static_cast<int>(m_plan.size())) {
        m_current = static_cast<int>(m_plan.size());
        m_screen = Screen::End;
        m_message = m_settings.end_text;
        m_actions.push_back({SessionAction::Kind::Finished, -1, {}});
        return;
    }
    m_current = next;
    const PlannedTrial& t = m_plan[static_cast<std::size_t>(next)];
    auto phase_text = [&](Phase phase) {
        switch (phase) {
            case Phase::Warmup: return m_settings.instructions;
            case Phase::Practice: return m_settings.practice_instructions;
            case Phase::Test: return m_settings.test_instructions;
        }
        return std::string();
    };
    if (first) {
        m_screen = Screen::Instructions;
        m_message = m_settings.instructions;
        if (m_resumed)
            m_message = "Welcome back. The session continues where it stopped.\n\n" + m_settings.instructions;
        if (t.phase != Phase::Warmup && phase_text(t.phase) != m_settings.instructions)
            m_message += "\n\n" + phase_text(t.phase);
        m_since_break = 0;
        return;
    }
    const PlannedTrial& p = m_plan[static_cast<std::size_t>(previous)];
    if (t.phase != p.phase) {
        m_screen = Screen::Instructions;
        m_message = phase_text(t.phase);
        m_since_break = 0;
        return;
    }
    const bool block_change = t.phase == Phase::Test && t.block != p.block;
    const bool every = m_settings.break_every > 0 && m_since_break >= m_settings.break_every;
    if (block_change || every) {
        m_screen = Screen::Break;
        m_message = m_settings.break_text;
        m_since_break = 0;
        return;
    }
    begin_fixation(now_s);
}

void SessionMachine::begin_fixation(double now_s) {
    m_screen = Screen::Fixation;
    m_state_start_s = now_s;
}

void SessionMachine::continue_pressed(double now_s) {
    switch (m_screen) {
        case Screen::Instructions:
        case Screen::Break: begin_fixation(now_s); break;
        case Screen::Feedback: go_to_next(now_s, false); break;
        default: break;
    }
}

void SessionMachine::tick(double now_s) {
    if (m_screen == Screen::Fixation && (now_s - m_state_start_s) * 1000.0 >= m_settings.fixation_ms - time_slack_ms) {
        m_screen = Screen::Stimulus;
        m_state_start_s = now_s;
        m_actions.push_back({SessionAction::Kind::StartStimulus, m_current, {}});
    } else if (m_screen == Screen::Wait &&
               (now_s - m_state_start_s) * 1000.0 >= m_settings.response_delay_ms - time_slack_ms) {
        m_screen = Screen::Response;
        m_state_start_s = now_s;
        m_response_start_s = now_s;
    }
}

void SessionMachine::stimulus_finished(double now_s) {
    if (m_screen != Screen::Stimulus) return;
    m_screen = Screen::Wait;
    m_state_start_s = now_s;
    tick(now_s);
}

void SessionMachine::submit(const std::string& text, double now_s) {
    if (m_screen != Screen::Response) return;
    if (blank(text)) {
        m_screen = Screen::ConfirmEmpty;
        return;
    }
    commit(text, false, now_s);
}

void SessionMachine::confirm_empty(bool accept, double now_s) {
    if (m_screen != Screen::ConfirmEmpty) return;
    if (!accept) {
        m_screen = Screen::Response;
        return;
    }
    commit("", true, now_s);
}

void SessionMachine::confirm_score(double now_s) {
    if (m_screen != Screen::ScoreCheck) return;
    SessionAction a;
    a.kind = SessionAction::Kind::CommitResponse;
    a.trial_index = m_current;
    a.response = m_pending;
    finish_commit(std::move(a), now_s);
}

void SessionMachine::commit(const std::string& text, bool confirmed_empty, double now_s) {
    SessionAction a;
    a.kind = SessionAction::Kind::CommitResponse;
    a.trial_index = m_current;
    a.response.text = text;
    a.response.response_time_ms = (now_s - m_response_start_s) * 1000.0;
    a.response.confirmed_empty = confirmed_empty;
    if (m_confirm_scores) {
        // The response time ends at Enter; the check is the experimenter's.
        m_pending = a.response;
        m_screen = Screen::ScoreCheck;
        return;
    }
    finish_commit(std::move(a), now_s);
}

void SessionMachine::finish_commit(SessionAction a, double now_s) {
    if (m_repeat_rule && m_repeat_rule(m_current, a.response)) {
        // The track presents this trial again: not answered yet.
        a.repeat = true;
        m_actions.push_back(std::move(a));
        begin_fixation(now_s);
        return;
    }
    m_actions.push_back(std::move(a));
    m_answered[static_cast<std::size_t>(m_current)] = true;
    ++m_answered_count;
    ++m_since_break;
    if (m_plan[static_cast<std::size_t>(m_current)].phase == Phase::Practice) {
        m_screen = Screen::Feedback;
        m_state_start_s = now_s;
        return;
    }
    go_to_next(now_s, false);
}

void SessionMachine::escape(double now_s) {
    if (m_screen == Screen::End) return;
    if (m_screen == Screen::Paused) {
        // A stimulus cut by the pause is shown again from its fixation.
        if (m_paused_from == Screen::Stimulus || m_paused_from == Screen::Fixation)
            begin_fixation(now_s);
        else
            m_screen = m_paused_from;
        return;
    }
    if (m_screen == Screen::Stimulus) m_actions.push_back({SessionAction::Kind::StopStimulus, m_current, {}});
    m_paused_from = m_screen;
    m_screen = Screen::Paused;
}

void SessionMachine::quit() {
    if (m_screen != Screen::Paused) return;
    m_actions.push_back({SessionAction::Kind::Quit, m_current, {}});
    m_screen = Screen::End;
    m_message = "The session was stopped. Run the same command again to continue where it stopped.";
}

std::vector<SessionAction> SessionMachine::take_actions() {
    std::vector<SessionAction> out;
    out.swap(m_actions);
    return out;
}

}  // namespace avsi::experiment
