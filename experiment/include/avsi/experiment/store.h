// Session storage: one SQLite database per experiment (WAL journal,
// synchronous = FULL, so a committed response survives a crash or power
// loss), schema-versioned through PRAGMA user_version. Tables: subjects,
// sessions (lab or online), planned_trials, presentations (timing summary per
// trial), frames (each frame's flip), responses, events; since version 2 also
// web_presentations (browser timing of online trials), screening_trials and
// screening (headphone checks of online sessions). A response and its
// presentation are committed in one transaction before the next trial starts;
// an online import (`avsi import-web`) is one transaction for all its subjects.
//
// Schema history: 1 = the lab runner's tables; 2 = sessions.mode and
// sessions.external_id, web_presentations, screening_trials, screening;
// 3 = adaptive_trials (every presentation of an adaptive SRT protocol: its
// level, score, correction, the track's step and the mixing gains).
// Opening an older database migrates it in place (one transaction).
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "avsi/experiment/design.h"

struct sqlite3;

namespace avsi::experiment {

// The schema version this build writes; older databases are migrated, newer
// ones are refused.
constexpr int store_schema_version = 3;

// Timing of one frame of a presented stimulus, in seconds on the audio clock.
struct FrameFlip {
    int frame = 0;          // index in the clip
    double pts_s = 0.0;     // its time in the clip
    double flip_s = 0.0;    // when it reached the screen (buffer swap)
    double offset_ms = 0.0; // (flip − audio onset) − pts: >0 means video late
};

// Timing of one stimulus presentation.
struct Presentation {
    double audio_onset_s = 0.0;  // first sample at the DAC (audio clock)
    double video_onset_s = 0.0;  // first frame's flip
    double duration_s = 0.0;
    double refresh_hz = 0.0;
    int frames_total = 0;        // frames in the clip
    int frames_shown = 0;
    int dropped_frames = 0;      // never shown
    int repeated_frames = 0;     // shown on more flips than the refresh/fps ratio
    double mean_offset_ms = 0.0;
    double max_abs_offset_ms = 0.0;
    std::vector<FrameFlip> flips;  // first flip of each frame shown
};

struct Response {
    std::string text;
    double response_time_ms = 0.0;  // from the answer box appearing to Enter
    bool confirmed_empty = false;
};

// One presentation of an adaptive SRT protocol (schema 3): the SNR it was
// mixed at, the live score (and the experimenter's correction), and the step
// of its track. Warm-up and practice trials have no track (track "") and are
// mixed at the protocol's fixed practice SNR.
struct AdaptiveRecord {
    int attempt = 1;              // presentation of this planned trial (first-sentence repeats)
    std::string track;            // the condition whose track it belongs to; "" for none
    int presentation = 0;         // 1-based within the track (0 without a track)
    int sentence_index = 0;       // 1-based sentence of the track
    double level_db = 0.0;        // the SNR presented
    int keywords = 0;
    int correct = 0;              // keywords counted (after a correction)
    int auto_correct = 0;         // keywords the live scorer credited
    std::string marks;            // per keyword, "1" right / "0" wrong, as counted
    bool corrected = false;       // the experimenter changed the live score
    double next_level_db = 0.0;   // the track's level for its next presentation
    double step_db = 0.0;
    bool reversal = false;
    int reversals = 0;
    bool repeat = false;          // the next presentation repeats this trial
    bool at_bound = false;
    double speech_gain_db = 0.0;  // applied to the stimulus audio (limiter included)
    double noise_gain_db = 0.0;   // noise RMS relative to full scale, dBFS, after the limiter
    double limit_gain_db = 0.0;   // < 0 when the mixture was scaled down to avoid clipping
    std::string response;         // what was typed for this presentation
    std::string answered_utc;

    bool operator==(const AdaptiveRecord&) const = default;
};

struct SessionInfo {
    int session = 0;
    int subject = 0;
    std::string started_utc;
    std::string ended_utc;   // "" while running or after a crash
    std::string end_reason;  // completed, quit, interrupted (online: completed, incomplete)
    int first_position = 0;  // the trial it started (resumed) at
    std::string mode = "lab";  // "lab" (avsi run) or "online" (avsi import-web)
    std::string external_id;   // online: the browser session's id
    std::string details;
};

// What a browser measured about one presentation beyond the Presentation
// fields (online sessions): the AudioContext's latencies and the video
// element's own frame counts.
struct WebPresentation {
    bool frame_callbacks = true;       // requestVideoFrameCallback was available
    int presented_frames = 0;          // frames the compositor presented (rVFC presentedFrames)
    int missed_callbacks = 0;          // presented frames without a callback (presentedFrames jumps)
    int browser_dropped_frames = 0;    // getVideoPlaybackQuality().droppedVideoFrames during the clip
    int browser_total_frames = 0;      // getVideoPlaybackQuality().totalVideoFrames during the clip
    double output_latency_ms = 0.0;    // AudioContext.outputLatency
    double base_latency_ms = 0.0;      // AudioContext.baseLatency
    double audio_path_ms = 0.0;        // output path used for the A/V offsets (from getOutputTimestamp when measured)
    bool audio_path_measured = false;  // audio_path_ms came from getOutputTimestamp (else outputLatency + baseLatency)
};

// One trial of a headphone check (online sessions).
struct ScreeningTrial {
    std::string test;        // "antiphase" or "huggins"
    int trial = 0;           // 1-based
    int answer = 0;          // the correct interval (1–3)
    int response = 0;        // the interval chosen (1–3)
    bool correct = false;
    double response_time_ms = 0.0;
};

// The outcome of one headphone check (online sessions).
struct ScreeningResult {
    std::string test;
    int trials = 0;
    int correct = 0;
    int required = 0;        // the protocol's pass criterion
    bool passed = false;
};

// One browser session (a page load) to store with `Store::import_online`.
struct OnlineSession {
    std::string external_id;  // the browser's session id
    std::string started_utc;
    std::string ended_utc;
    std::string end_reason;   // completed, incomplete
    std::string details;      // browser, refresh rate, audio latencies, study id
    int first_position = 0;
    struct Trial {
        PlannedTrial trial;
        Presentation presentation;
        WebPresentation web;
        Response response;
        std::string answered_utc;
        // Where the record came from (results file, line, column), for errors.
        std::string source_file;
        int source_line = 0;
        int source_column = 0;
    };
    std::vector<Trial> trials;
    std::vector<ScreeningTrial> screening_trials;
    std::vector<ScreeningResult> screening;
    std::vector<std::pair<std::string, std::string>> events;  // kind, detail
};

// One online subject: the plan and the sessions to store.
struct OnlineSubject {
    int subject = 0;
    std::vector<PlannedTrial> plan;
    std::vector<OnlineSession> sessions;
};

// What an online import changed.
struct OnlineImportCounts {
    int subjects_added = 0;
    int sessions_added = 0;
    int trials_added = 0;
    int trials_present = 0;   // already stored, identical (a repeated import)
};

// One row of the responses export.
struct ResponseRow {
    PlannedTrial trial;
    int session = 0;
    Response response;
    std::string answered_utc;
    std::string mode;  // of the session that answered: lab or online
};

class Store {
public:
    // Opens or creates the database. Throws InputError if the file is not an
    // avsi database or was written by a newer avsi (schema too new).
    explicit Store(const std::filesystem::path& path);
    ~Store();
    Store(const Store&) = delete;
    Store& operator=(const Store&) = delete;

    const std::filesystem::path& path() const { return m_path; }
    int schema_version() const;

    // Experiment-level metadata (protocol name, path, hash).
    void set_meta(const std::string& key, const std::string& value);
    std::optional<std::string> meta(const std::string& key) const;

    // The subject's planned trials; empty if the subject is new.
    std::vector<PlannedTrial> planned_trials(int subject) const;
    // Records a new subject with their plan (one transaction).
    void add_subject(int subject, const std::vector<PlannedTrial>& trials);

    // Positions of the subject's answered trials.
    std::vector<int> answered_positions(int subject) const;

    // Sessions of a subject left open (started, never ended): crashes.
    std::vector<SessionInfo> open_sessions(int subject) const;
    std::vector<SessionInfo> sessions(int subject) const;
    // Starts a session and returns its id.
    int begin_session(int subject, int first_position, const std::string& details);
    void end_session(int session, const std::string& reason);
    // Marks an open session as interrupted (found open when the subject resumed).
    void mark_interrupted(int session);

    void add_event(int session, int subject, const std::string& kind, const std::string& detail);

    // Takes the runner's advisory lock on `subject` for this process (a row
    // of the runner_locks table, created on first use; not part of the
    // versioned schema, older avsi ignore it). Throws InputError naming the
    // database and the holder (pid, host, since when) if a running process
    // holds it. A lock whose process is gone (crash, kill; checked by pid,
    // process start time and boot id on the same host) is broken: returns a
    // description of it then, "" otherwise. Released by unlock_subject or the
    // Store's destructor.
    std::string lock_subject(int subject);
    void unlock_subject(int subject);

    // Commits the presentation and response of one trial in one durable
    // transaction. Throws if the trial already has a response (never asked twice).
    void commit_trial(int session, const PlannedTrial& trial, const Presentation& presentation,
                      const Response& response);
    // The same with the trial's adaptive record, in the same transaction.
    void commit_trial(int session, const PlannedTrial& trial, const Presentation& presentation,
                      const Response& response, const AdaptiveRecord& adaptive);
    // Commits a presentation that the track repeats (no response row: the
    // trial is answered by its last presentation). Throws if the trial
    // already has a response or this attempt is stored.
    void commit_attempt(int session, const PlannedTrial& trial, const AdaptiveRecord& adaptive);

    struct AdaptiveRow {
        int subject = 0;
        int position = 0;
        int session = 0;
        AdaptiveRecord record;
    };
    // Adaptive records (ordered by subject, position, attempt); subject 0: all.
    std::vector<AdaptiveRow> adaptive_trials(int subject = 0) const;

    // Stores imported online subjects in one transaction: new subjects with
    // their plan, each browser session (marked online; one already stored
    // under the same external id is reused), each new trial's response,
    // presentation, frames and browser timing, screening results and events.
    // A response already stored identically is skipped. Throws InputError
    // naming the database, and changes nothing, if a subject's stored plan
    // differs or a stored response at the same position differs (or came
    // from a lab session).
    OnlineImportCounts import_online(const std::vector<OnlineSubject>& subjects, const std::string& event_detail);

    // Every response (ordered by subject, position) and every presentation.
    std::vector<ResponseRow> responses() const;
    struct TimingRow {
        int subject = 0;
        int position = 0;
        int session = 0;
        Presentation presentation;
    };
    std::vector<TimingRow> timing(bool with_frames) const;
    struct WebTimingRow {
        int subject = 0;
        int position = 0;
        WebPresentation web;
    };
    std::vector<WebTimingRow> web_timing() const;
    struct ScreeningRow {
        int subject = 0;
        int session = 0;
        ScreeningResult result;
    };
    std::vector<ScreeningRow> screening() const;
    struct ScreeningTrialRow {
        int subject = 0;
        int session = 0;
        ScreeningTrial trial;
    };
    std::vector<ScreeningTrialRow> screening_trials() const;
    struct EventRow {
        int session = 0;
        int subject = 0;
        std::string time_utc;
        std::string kind;
        std::string detail;
    };
    std::vector<EventRow> events() const;
    std::vector<int> subjects() const;

private:
    void exec(const std::string& sql) const;
    std::filesystem::path m_path;
    sqlite3* m_db = nullptr;
    std::vector<int> m_locked_subjects;
};

// Writes responses.csv, timing.csv, timing_summary.csv, frames.csv,
// sessions.csv and events.csv into `out_dir`, for databases with online
// sessions web_timing.csv, screening.csv and screening_trials.csv, and for
// adaptive protocols adaptive_trials.csv (every presentation); returns
// the files written. responses.csv and sessions.csv end with a `mode` column
// (lab or online).
std::vector<std::filesystem::path> export_store(const Store& store, const std::filesystem::path& out_dir);

// UTC now as ISO 8601 with milliseconds.
std::string utc_now();

}  // namespace avsi::experiment
