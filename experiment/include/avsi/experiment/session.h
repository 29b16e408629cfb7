// The session as a pure state machine: which screen is up, which trial is
// current, and what the front end must do next (start a stimulus, commit a
// response). No window, clock or device here — the front end feeds it
// inputs with timestamps — so the whole flow is testable headless.
//
//   Instructions ─continue→ Fixation ─fixation_ms→ Stimulus ─finished→ Wait
//   ─response_delay_ms→ Response ─Enter→ (empty? ConfirmEmpty) → (adaptive
//   tracks with confirm_scores: ScoreCheck ─Enter→) commit →
//   Feedback (practice: the sentence text) → next trial: Fixation, or
//   Instructions at a phase change, Break between blocks / every N trials,
//   End after the last. Esc pauses from anywhere; a stimulus interrupted by a
//   pause is shown again from the start.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "avsi/core/protocol.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/store.h"

namespace avsi::experiment {

enum class Screen { Instructions, Fixation, Stimulus, Wait, Response, ConfirmEmpty, ScoreCheck, Feedback, Break, Paused, End };
std::string to_string(Screen screen);

struct SessionAction {
    enum class Kind { StartStimulus, StopStimulus, CommitResponse, Finished, Quit };
    Kind kind = Kind::StartStimulus;
    int trial_index = -1;  // index into the plan
    Response response;     // for CommitResponse
    bool repeat = false;   // CommitResponse of a presentation the adaptive track repeats
};

class SessionMachine {
public:
    // `plan`: the subject's planned trials in order; `answered`: positions that
    // already have a response (a resumed session skips them).
    SessionMachine(std::vector<PlannedTrial> plan, const std::vector<int>& answered,
                   SessionSettings settings);

    Screen screen() const { return m_screen; }
    // The screen under the pause overlay (or the screen itself).
    Screen underlying_screen() const { return m_screen == Screen::Paused ? m_paused_from : m_screen; }
    // The current trial, or nullptr before the first / after the last.
    const PlannedTrial* trial() const;
    int trial_index() const { return m_current; }
    // Text for Instructions, Break and End screens.
    const std::string& message() const { return m_message; }
    // Whether this start resumes an interrupted session.
    bool resumed() const { return m_resumed; }
    int answered_count() const { return m_answered_count; }
    int total_trials() const { return static_cast<int>(m_plan.size()); }
    bool finished() const { return m_screen == Screen::End; }
    const std::vector<PlannedTrial>& plan() const { return m_plan; }

    // Space/Enter on an Instructions, Break or Feedback screen.
    void continue_pressed(double now_s);
    // Time passing: ends the fixation and the post-stimulus wait.
    void tick(double now_s);
    // The stimulus has played to its end.
    void stimulus_finished(double now_s);
    // Enter in the answer box. An empty answer asks for confirmation first.
    void submit(const std::string& text, double now_s);
    // The answer to "submit an empty answer?".
    void confirm_empty(bool accept, double now_s);
    // With score confirmation on, an answer waits on the ScoreCheck screen
    // (the experimenter checks or corrects the live score) until this call.
    void set_confirm_scores(bool on) { m_confirm_scores = on; }
    // Enter on the ScoreCheck screen: the answer counts.
    void confirm_score(double now_s);
    // The answer waiting on the ScoreCheck screen.
    const Response& pending_response() const { return m_pending; }

    // Esc: pause, or resume when paused.
    void escape(double now_s);
    // From the pause screen: end the session now (resumable later).
    void quit();

    // Adaptive tracks: asked at each answer whether the trial is presented
    // again (the first-sentence rule). A repeated trial is not marked answered;
    // its CommitResponse action has repeat = true and the trial starts again
    // from its fixation.
    void set_repeat_rule(std::function<bool(int trial_index, const Response& response)> rule) {
        m_repeat_rule = std::move(rule);
    }

    // Actions for the front end, in order; clears the queue.
    std::vector<SessionAction> take_actions();

private:
    void go_to_next(double now_s, bool first);
    void finish_commit(SessionAction action, double now_s);
    void begin_fixation(double now_s);
    void commit(const std::string& text, bool confirmed_empty, double now_s);

    std::vector<PlannedTrial> m_plan;
    std::vector<bool> m_answered;
    SessionSettings m_settings;
    Screen m_screen = Screen::Instructions;
    Screen m_paused_from = Screen::Instructions;
    int m_current = -1;
    int m_answered_count = 0;
    int m_since_break = 0;
    bool m_resumed = false;
    double m_state_start_s = 0.0;
    double m_response_start_s = 0.0;
    std::string m_message;
    std::vector<SessionAction> m_actions;
    std::function<bool(int, const Response&)> m_repeat_rule;
    bool m_confirm_scores = false;
    Response m_pending;
};

}  // namespace avsi::experiment
