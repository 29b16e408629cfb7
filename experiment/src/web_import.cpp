// `avsi import-web`: online results back into the session database (see
// web_study.h). The study runtime (web/src/avsi-study.js) sends one JSON
// object per event, each followed by a newline: under JATOS through
// jatos.appendResultData (so JATOS' "data only" export is JSON Lines, and its
// results archive holds the same lines in study_result_<id>/comp-result_<id>/data.txt),
// otherwise to a POST endpoint or into a download. jsPsych's own JSON export
// (an array of every trial's data) holds the same objects among other
// plugins' rows. Every record carries "avsi" (its kind), the study id, the
// experiment, the subject, the browser session and a per-subject sequence
// number, so the answers' order survives reloads and mixed sources.
#include <algorithm>
#include <map>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/log.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/runner.h"
#include "avsi/experiment/store.h"
#include "avsi/experiment/web_study.h"
#include "zip_archive.h"

namespace avsi::experiment {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::size_t max_frames_per_trial = 100000;

// One JSON object read from a results file, with where it starts.
struct Record {
    json value;
    std::string file;
    int line = 0;
    int column = 0;
    std::string where;  // "" or "[i]" for an element of a top-level array
    std::string input;  // the results file given (an archive's entries share it)

    // The field name in messages: "[i].key" inside an array, else "key".
    std::string field(const std::string& key) const { return where.empty() ? key : where + "." + key; }
};

// Line and column (1-based) of a byte offset.
std::pair<int, int> line_column(const std::string& text, std::size_t offset) {
    int line = 1, column = 1;
    for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
        if (text[i] == '\n') {
            ++line;
            column = 1;
        } else {
            ++column;
        }
    }
    return {line, column};
}

// The JSON values of a text: JSON Lines, concatenated objects, or arrays of
// objects (jsPsych's export). Objects with an "avsi" key are records; others
// are counted in `ignored`.
void parse_records(const std::string& text, const std::string& file, std::vector<Record>& out, int& ignored) {
    check_json_structure(text, file);
    std::istringstream in(text);
    bool any = false;
    while (true) {
        in >> std::ws;
        if (in.peek() == std::char_traits<char>::eof()) break;
        const auto start = static_cast<std::size_t>(in.tellg());
        json value;
        try {
            in >> value;
        } catch (const json::parse_error& e) {
            const auto [line, column] = line_column(text, start + (e.byte > 0 ? e.byte - 1 : 0));
            // nlohmann's text without its own (value-relative) position: "syntax error while parsing …".
            std::string what = e.what();
            if (const auto p = what.find("syntax error"); p != std::string::npos) what = what.substr(p);
            throw InputError(file, line, column, "",
                             fmt::format("not valid JSON, the file is truncated or damaged ({}); nothing was imported",
                                         what));
        }
        any = true;
        const auto position = line_column(text, start);  // not a structured binding: captured below (clang 14)
        const auto line = position.first, column = position.second;
        auto take = [&](json&& v, const std::string& where) {
            if (v.is_object() && v.contains("avsi"))
                out.push_back({std::move(v), file, line, column, where, ""});
            else
                ++ignored;
        };
        if (value.is_array()) {
            for (std::size_t i = 0; i < value.size(); ++i) take(std::move(value[i]), fmt::format("[{}]", i));
        } else {
            take(std::move(value), "");
        }
    }
    if (!any) throw InputError(fs::path(file), "empty: no results in this file");
}

// Reads a results file: a ZIP (JATOS results archive) or text.
void read_results_file(const fs::path& path, std::vector<Record>& out, int& ignored) {
    if (!fs::is_regular_file(path)) throw InputError(path, "no such results file");
    const std::string bytes = read_text_file(path);
    if (bytes.rfind("PK\x03\x04", 0) == 0 || bytes.rfind("PK\x05\x06", 0) == 0) {
        const detail::ZipReader zip(path);
        std::vector<std::string> names;
        for (const auto& name : zip.names()) {
            if (name.empty() || name.back() == '/' || fs::path(name).filename() == "metadata.json") continue;
            const std::string ext = fs::path(name).extension().string();
            if (ext == ".txt" || ext == ".json" || ext == ".jsonl") names.push_back(name);
        }
        if (names.empty())
            throw InputError(path, "the archive holds no result data (expected study_result_<id>/comp-result_<id>/data.txt, "
                                   "JATOS' results archive layout)");
        std::sort(names.begin(), names.end());
        for (const auto& name : names) {
            const std::string text = zip.read(name);
            if (text.find_first_not_of(" \t\r\n") == std::string::npos) continue;  // a component result without data
            parse_records(text, path.string() + ":" + name, out, ignored);
        }
        return;
    }
    parse_records(bytes, path.string(), out, ignored);
}

// Typed access to a record's fields; problems are collected with the record's location.
class Fields {
public:
    Fields(const Record& r, const json& object, std::string prefix, DiagnosticList& problems)
        : m_record(r), m_object(object), m_prefix(std::move(prefix)), m_problems(problems) {}

    const json* find(const std::string& key, bool required = true) const {
        const auto it = m_object.find(key);
        if (it == m_object.end() || it->is_null()) {
            if (required) report(key, "missing");
            return nullptr;
        }
        return &*it;
    }
    std::string str(const std::string& key, bool required = true) const {
        const json* v = find(key, required);
        if (!v) return "";
        if (!v->is_string()) {
            report(key, fmt::format("expected a string, got {}", v->dump()));
            return "";
        }
        return v->get<std::string>();
    }
    long long integer(const std::string& key, long long lo, long long hi, bool required = true) const {
        const json* v = find(key, required);
        if (!v) return lo;
        if (!v->is_number_integer() || v->get<long long>() < lo || v->get<long long>() > hi) {
            report(key, fmt::format("expected an integer in [{}, {}], got {}", lo, hi, v->dump()));
            return lo;
        }
        return v->get<long long>();
    }
    double number(const std::string& key, bool required = true) const {
        const json* v = find(key, required);
        if (!v) return 0.0;
        if (!v->is_number()) {
            report(key, fmt::format("expected a number, got {}", v->dump()));
            return 0.0;
        }
        return v->get<double>();
    }
    bool boolean(const std::string& key, bool required = true) const {
        const json* v = find(key, required);
        if (!v) return false;
        if (!v->is_boolean()) {
            report(key, fmt::format("expected true or false, got {}", v->dump()));
            return false;
        }
        return v->get<bool>();
    }
    const json* object(const std::string& key) const {
        const json* v = find(key);
        if (v && !v->is_object()) {
            report(key, fmt::format("expected an object, got {}", v->dump().substr(0, 60)));
            return nullptr;
        }
        return v;
    }
    void report(const std::string& key, const std::string& message) const {
        m_problems.add(m_record.file, m_record.line, m_record.column,
                       m_record.field(m_prefix.empty() ? key : m_prefix + "." + key), message);
    }
    const Record& record() const { return m_record; }

private:
    const Record& m_record;
    const json& m_object;
    std::string m_prefix;
    DiagnosticList& m_problems;
};

// A trial record, parsed.
struct TrialRecord {
    const Record* record = nullptr;
    long long seq = 0;
    std::string session;
    PlannedTrial trial;
    std::string stimulus_sha256;
    Response response;
    std::string answered_utc;
    Presentation presentation;
    WebPresentation web;
};

struct SessionRecord {
    const Record* record = nullptr;
    std::string time_utc;
    int first_position = 0;
    std::string details;
};

// One run of one subject: the records of one browser's localStorage (every
// page load of it), from the run's first session on.
struct SubjectRecords {
    std::string started_utc;   // its earliest record
    std::vector<TrialRecord> trials;
    std::map<std::string, SessionRecord> sessions;       // by browser session id
    std::map<std::string, std::string> last_time;        // latest record time per session
    std::map<std::string, std::vector<ScreeningTrial>> screening_trials;
    std::map<std::string, std::vector<ScreeningResult>> screening;
    std::map<std::string, std::vector<std::pair<std::string, std::string>>> events;
};

std::string describe_browser(const json& j) {
    std::string out;
    for (const auto& [key, value] : j.items()) {
        if (!out.empty()) out += "; ";
        out += key + "=" + (value.is_string() ? value.get<std::string>() : value.dump());
    }
    return out;
}

// The distinct trial positions a run answered.
int answered_positions(const SubjectRecords& run) {
    std::set<int> positions;
    for (const auto& t : run.trials) positions.insert(t.trial.position);
    return static_cast<int>(positions.size());
}

// The run to keep of a subject's runs (by the rule), or "" after reporting
// why none can be chosen.
std::string choose_run(int subject, const std::map<std::string, SubjectRecords>& runs, const RunChoice& choice,
                       DiagnosticList& problems) {
    if (runs.size() == 1) return runs.begin()->first;
    auto describe = [&] {
        std::string out;
        for (const auto& [id, run] : runs) {
            std::string sessions;
            for (const auto& [session, record] : run.sessions) sessions += (sessions.empty() ? "" : ",") + session;
            out += fmt::format("{}run {} (started {}, {} trials, sessions {})", out.empty() ? "" : "; ",
                               id.empty() ? "(none)" : id, run.started_utc, answered_positions(run),
                               sessions.empty() ? "none" : sessions);
        }
        return out;
    };
    const Record* first = nullptr;
    for (const auto& [id, run] : runs)
        if (!run.trials.empty() && (!first || run.trials.front().record->line < first->line)) first = run.trials.front().record;
    if (!first)
        for (const auto& [id, run] : runs)
            for (const auto& [session, record] : run.sessions)
                if (!first) first = record.record;
    auto fail = [&](const std::string& message) {
        if (first) problems.add(first->file, first->line, first->column, first->field("run"), message);
        else problems.add("", 0, 0, "run", message);
        return std::string();
    };
    using Entry = std::pair<const std::string, SubjectRecords>;
    std::vector<const Entry*> order;
    for (const auto& entry : runs) order.push_back(&entry);
    std::stable_sort(order.begin(), order.end(),
                     [](const Entry* a, const Entry* b) { return a->second.started_utc < b->second.started_utc; });
    switch (choice.rule) {
    case RunRule::Refuse:
        return fail(fmt::format("subject {} took the study in {} browser runs ({}); choose the run to keep with "
                                "--runs first|last|most-complete|session=ID",
                                subject, runs.size(), describe()));
    case RunRule::First: return order.front()->first;
    case RunRule::Last: return order.back()->first;
    case RunRule::MostComplete: {
        const Entry* best = order.front();
        for (const Entry* e : order)
            if (answered_positions(e->second) > answered_positions(best->second)) best = e;
        return best->first;
    }
    case RunRule::Session: {
        std::vector<std::string> chosen;
        for (const auto& [id, run] : runs)
            for (const auto& session : choice.sessions)
                if (run.sessions.count(session) || std::any_of(run.trials.begin(), run.trials.end(),
                                                               [&](const TrialRecord& t) { return t.session == session; }))
                    chosen.push_back(id);
        chosen.erase(std::unique(chosen.begin(), chosen.end()), chosen.end());
        if (chosen.size() == 1) return chosen.front();
        return fail(fmt::format("--runs session=…: subject {} has {} runs holding the given sessions, expected "
                                "exactly one; its runs: {}",
                                subject, chosen.size(), describe()));
    }
    }
    return "";
}

}  // namespace

RunChoice parse_run_choice(const std::string& text) {
    RunChoice c;
    if (text == "first") c.rule = RunRule::First;
    else if (text == "last") c.rule = RunRule::Last;
    else if (text == "most-complete") c.rule = RunRule::MostComplete;
    else if (text.rfind("session=", 0) == 0 && text.size() > 8) {
        c.rule = RunRule::Session;
        std::string rest = text.substr(8);
        std::size_t start = 0;
        while (start <= rest.size()) {
            const std::size_t comma = rest.find(',', start);
            const std::string id = rest.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
            if (id.empty()) throw UsageError(fmt::format("--runs: expected session=ID[,ID…], got \"{}\"", text));
            c.sessions.push_back(id);
            if (comma == std::string::npos) break;
            start = comma + 1;
        }
    } else {
        throw UsageError(fmt::format("--runs: expected first, last, most-complete or session=ID[,ID…], got \"{}\"", text));
    }
    return c;
}

namespace {

// Every avsi record of the results files, each knowing its file.
std::vector<Record> read_records(const ImportWebSettings& settings, ImportWebResult& result) {
    std::vector<Record> records;
    for (const auto& path : settings.results) {
        const std::size_t before = records.size();
        read_results_file(path, records, result.ignored);
        for (std::size_t i = before; i < records.size(); ++i) records[i].input = path.string();
    }
    result.records = static_cast<int>(records.size());
    if (records.empty())
        throw InputError(settings.results.front(), "no avsi records in the results (objects with an \"avsi\" field, "
                                                   "written by a study from `avsi export-web`)");
    return records;
}

// A trial record's presentation timing (the "timing" object): the lab's
// presentation fields and the browser's own.
void read_trial_timing(const Fields& g, TrialRecord& t) {
    Presentation& p = t.presentation;
    p.audio_onset_s = g.number("audio_onset_s");
    p.video_onset_s = g.number("video_onset_s");
    p.duration_s = g.number("duration_s");
    p.refresh_hz = g.number("refresh_hz");
    p.frames_total = static_cast<int>(g.integer("frames_total", 0, max_frames_per_trial));
    p.frames_shown = static_cast<int>(g.integer("frames_shown", 0, max_frames_per_trial));
    p.dropped_frames = static_cast<int>(g.integer("dropped_frames", 0, max_frames_per_trial));
    p.repeated_frames = static_cast<int>(g.integer("repeated_frames", 0, max_frames_per_trial));
    p.mean_offset_ms = g.number("mean_offset_ms");
    p.max_abs_offset_ms = g.number("max_abs_offset_ms");
    WebPresentation& w = t.web;
    w.frame_callbacks = g.boolean("frame_callbacks");
    w.presented_frames = static_cast<int>(g.integer("presented_frames", 0, max_frames_per_trial));
    w.missed_callbacks = static_cast<int>(g.integer("missed_callbacks", 0, max_frames_per_trial));
    w.browser_dropped_frames = static_cast<int>(g.integer("browser_dropped_frames", 0, max_frames_per_trial));
    w.browser_total_frames = static_cast<int>(g.integer("browser_total_frames", 0, max_frames_per_trial));
    w.output_latency_ms = g.number("output_latency_ms");
    w.base_latency_ms = g.number("base_latency_ms");
    w.audio_path_ms = g.number("audio_path_ms");
    w.audio_path_measured = g.boolean("audio_path_measured");
}

// A trial record's displayed frames ("frames": [frame, pts_s, display_s, offset_ms] rows).
void read_trial_frames(const Fields& f, TrialRecord& t) {
    const json* frames = f.find("frames");
    if (!frames) return;
    if (!frames->is_array() || frames->size() > max_frames_per_trial) {
        f.report("frames", fmt::format("expected an array of at most {} [frame, pts_s, display_s, offset_ms] rows",
                                       max_frames_per_trial));
        return;
    }
    for (const auto& row : *frames) {
        if (!row.is_array() || row.size() != 4 || !row[0].is_number_integer() || !row[1].is_number() ||
            !row[2].is_number() || !row[3].is_number()) {
            f.report("frames", fmt::format("expected [frame, pts_s, display_s, offset_ms] rows, got {}",
                                           row.dump().substr(0, 60)));
            break;
        }
        t.presentation.flips.push_back(
            {row[0].get<int>(), row[1].get<double>(), row[2].get<double>(), row[3].get<double>()});
    }
}

// A "trial" record: the planned trial, the response and its presentation.
TrialRecord read_trial_record(const Record& r, const Fields& f, int subject, long long seq, const std::string& session,
                              const std::string& time_utc, DiagnosticList& problems) {
    TrialRecord t;
    t.record = &r;
    t.seq = seq;
    t.session = session;
    t.trial.subject = subject;
    t.trial.position = static_cast<int>(f.integer("position", 1, 1000000));
    const std::string phase = f.str("phase");
    if (!phase.empty() && !parse_phase(phase, t.trial.phase))
        f.report("phase", fmt::format("expected \"warmup\", \"practice\" or \"test\", got \"{}\"", phase));
    t.trial.block = static_cast<int>(f.integer("block", 0, 1000000));
    t.trial.list = f.str("list");
    t.trial.condition = f.str("condition");
    t.trial.sentence = f.str("sentence");
    t.trial.stimulus = f.str("stimulus");
    t.stimulus_sha256 = f.str("stimulus_sha256");
    t.response.text = f.str("response");
    t.response.response_time_ms = f.number("response_time_ms");
    t.response.confirmed_empty = f.boolean("confirmed_empty");
    t.answered_utc = time_utc;
    if (const json* timing = f.object("timing")) read_trial_timing(Fields(r, *timing, "timing", problems), t);
    read_trial_frames(f, t);
    return t;
}

// The identity of a record: the same record read twice (a .txt and a .jrzip
// of the same study, a resend) has the same.
std::string record_identity(const json& v) {
    auto text_of = [&](const char* key) { return v.contains(key) ? v[key].dump() : std::string("null"); };
    return text_of("subject") + "|" + text_of("run") + "|" + text_of("session") + "|" + text_of("seq") + "|" +
           text_of("avsi");
}

// Adds a record of the kinds other than "trial" to its run: a session's
// start, a headphone check's trial or result, the level setting, a failed
// preload, the end.
void add_session_record(const Record& r, const Fields& f, const std::string& kind, const std::string& study,
                        const std::string& session, const std::string& time_utc, SubjectRecords& s) {
    if (kind == "session") {
        SessionRecord sr;
        sr.record = &r;
        sr.time_utc = time_utc;
        sr.first_position = static_cast<int>(f.integer("position", 0, 1000000));
        std::string details = "mode=online; study=" + study;
        if (const json* browser = f.object("browser")) details += "; " + describe_browser(*browser);
        sr.details = details;
        if (!s.sessions.count(session) || time_utc < s.sessions[session].time_utc) s.sessions[session] = sr;
    } else if (kind == "screening-trial") {
        ScreeningTrial t;
        t.test = f.str("test");
        t.trial = static_cast<int>(f.integer("trial", 1, 100));
        t.answer = static_cast<int>(f.integer("answer", 1, 3));
        t.response = static_cast<int>(f.integer("response", 1, 3));
        t.correct = f.boolean("correct");
        t.response_time_ms = f.number("response_time_ms");
        if (t.correct != (t.answer == t.response))
            f.report("correct", fmt::format("says {} but the answer is {} and the response {}", t.correct, t.answer,
                                            t.response));
        s.screening_trials[session].push_back(t);
    } else if (kind == "screening") {
        ScreeningResult sr;
        sr.test = f.str("test");
        sr.trials = static_cast<int>(f.integer("trials", 1, 100));
        sr.correct = static_cast<int>(f.integer("correct", 0, 100));
        sr.required = static_cast<int>(f.integer("required", 0, 100));
        sr.passed = f.boolean("passed");
        if (sr.passed != (sr.correct >= sr.required))
            f.report("passed", fmt::format("says {} with {} of {} correct and {} required", sr.passed, sr.correct,
                                           sr.trials, sr.required));
        s.screening[session].push_back(sr);
        s.events[session].emplace_back("screening", fmt::format("{}: {} of {} correct, {} required: {}", sr.test,
                                                                sr.correct, sr.trials, sr.required,
                                                                sr.passed ? "passed" : "failed"));
    } else if (kind == "level") {
        s.events[session].emplace_back("level-setting", fmt::format("calibration noise played {:.1f} s until "
                                                                    "confirmed comfortable",
                                                                    f.number("played_ms") / 1000.0));
    } else if (kind == "preload-failed") {
        s.events[session].emplace_back("preload-failed", r.value.dump());
    } else if (kind == "end") {
        s.events[session].emplace_back("end", fmt::format("{} of {} answered", f.integer("answered", 0, 1000000),
                                                          f.integer("total", 0, 1000000)));
    } else if (!kind.empty()) {
        f.report("avsi", fmt::format("expected a record kind (session, level, screening-trial, screening, trial, "
                                     "preload-failed, end), got \"{}\"",
                                     kind));
    }
}

// The records by subject and run, each parsed and checked on its own; a
// record of another experiment or of a subject's second study export is an
// error (one per file and experiment, or subject and export, with a count).
std::map<int, std::map<std::string, SubjectRecords>> collect_runs(const std::vector<Record>& records,
                                                                  const Protocol& protocol, ImportWebResult& result,
                                                                  DiagnosticList& problems) {
    std::map<int, std::map<std::string, SubjectRecords>> subject_runs;  // subject → run id → records
    std::map<int, std::pair<std::string, const Record*>> subject_study;  // subject → study id, first record
    // Another study's records: one error per results file and experiment, with a count.
    std::map<std::pair<std::string, std::string>, std::pair<const Record*, int>> foreign;
    // A subject's records of a second study export: one error per subject and export, with a count.
    std::map<std::pair<int, std::string>, std::pair<const Record*, int>> other_export;
    // The same record read twice (a .txt and a .jrzip of the same study, a resend): once.
    std::set<std::string> seen;
    for (const Record& r : records) {
        if (!seen.insert(record_identity(r.value)).second) {
            ++result.duplicates;
            continue;
        }
        const Fields f(r, r.value, "", problems);
        const std::string kind = f.str("avsi");
        const std::string experiment = f.str("experiment");
        if (!experiment.empty() && experiment != protocol.name) {
            auto& [first, count] = foreign[{r.input, experiment}];
            if (!first) first = &r;
            ++count;
            continue;
        }
        const int subject = static_cast<int>(f.integer("subject", 1, 1000000));
        const std::string study = f.str("study");
        const std::string run = f.str("run", false);
        const std::string session = f.str("session");
        const long long seq = f.integer("seq", 0, 1LL << 40);
        const std::string time_utc = f.str("time_utc");
        auto& [first_study, first_record] = subject_study[subject];
        if (!first_record) {
            first_record = &r;
            first_study = study;
        } else if (study != first_study && !study.empty()) {
            auto& [first, count] = other_export[{subject, study}];
            if (!first) first = &r;
            ++count;
            continue;
        }
        SubjectRecords& s = subject_runs[subject][run];
        if (s.started_utc.empty() || time_utc < s.started_utc) s.started_utc = time_utc;
        if (!session.empty() && time_utc > s.last_time[session]) s.last_time[session] = time_utc;
        if (kind == "trial")
            s.trials.push_back(read_trial_record(r, f, subject, seq, session, time_utc, problems));
        else
            add_session_record(r, f, kind, study, session, time_utc, s);
    }
    for (const auto& [key, found] : other_export) {
        const auto& [r, count] = found;
        const auto& [first_study, first_record] = subject_study.at(key.first);
        problems.add(r->file, r->line, r->column, r->field("study"),
                     fmt::format("subject {} has records of two study exports ({} and {}, the first at {}:{}; {} "
                                 "record{} of {}); import each export's results into its own database",
                                 key.first, first_study, key.second, first_record->file, first_record->line, count,
                                 count == 1 ? "" : "s", key.second));
    }
    for (const auto& [key, found] : foreign) {
        const auto& [r, count] = found;
        problems.add(r->file, r->line, r->column, r->field("experiment"),
                     fmt::format("expected \"{}\" (the protocol's experiment), got \"{}\": these are another study's "
                                 "results ({} record{} of {} with this experiment)",
                                 protocol.name, key.second, count, count == 1 ? "" : "s", key.first));
    }
    return subject_runs;
}

// One run per subject (settings.runs); the others are reported as left out.
std::map<int, SubjectRecords> choose_runs(std::map<int, std::map<std::string, SubjectRecords>>& subject_runs,
                                          const RunChoice& choice, ImportWebResult& result, DiagnosticList& problems) {
    std::map<int, SubjectRecords> subjects;
    for (auto& [subject, runs] : subject_runs) {
        const std::string kept = choose_run(subject, runs, choice, problems);
        if (kept.empty() && runs.size() > 1) continue;
        for (auto& [id, run] : runs) {
            if (id == kept) continue;
            LeftOutRun left;
            left.subject = subject;
            left.run = id;
            left.kept_run = kept;
            left.trials = answered_positions(run);
            left.kept_trials = answered_positions(runs.at(kept));
            left.started_utc = run.started_utc;
            for (const auto& [session, record] : run.sessions) left.sessions.push_back(session);
            result.left_out.push_back(std::move(left));
        }
        subjects[subject] = std::move(runs.at(kept));
    }
    return subjects;
}

// A subject's trials in send order with duplicates (the same trial sent
// twice, or from two sources) collapsed; two different answers to one trial
// are an error.
std::vector<TrialRecord*> unique_trials(SubjectRecords& s, int subject, ImportWebResult& result,
                                        DiagnosticList& problems) {
    std::stable_sort(s.trials.begin(), s.trials.end(),
                     [](const TrialRecord& a, const TrialRecord& b) { return a.seq < b.seq; });
    std::map<int, const TrialRecord*> by_position;
    std::vector<TrialRecord*> unique;
    for (auto& t : s.trials) {
        const auto [it, inserted] = by_position.emplace(t.trial.position, &t);
        if (inserted) {
            unique.push_back(&t);
            continue;
        }
        // The same answer sent twice (or from two page loads) is one answer: compared by its text.
        const TrialRecord& first = *it->second;
        if (first.response.text == t.response.text && first.response.confirmed_empty == t.response.confirmed_empty) {
            ++result.duplicates;
            continue;
        }
        problems.add(t.record->file, t.record->line, t.record->column, t.record->field("position"),
                     fmt::format("subject {} trial {} has two different answers (\"{}\" at {}:{}, \"{}\" here)",
                                 subject, t.trial.position, first.response.text, first.record->file,
                                 first.record->line, t.response.text));
    }
    return unique;
}

// A subject's trials against the design: in plan order, the planned trials,
// stimuli of the manifest with its hashes, each browser session recorded.
void check_against_design(const ImportWebSettings& settings, const StimulusManifest& manifest,
                          const std::vector<PlannedTrial>& plan, const SubjectRecords& s,
                          const std::vector<TrialRecord*>& unique, int subject, DiagnosticList& problems) {
    int expected = 1;
    // Stimulus hashes not the manifest's: one error per subject, with the count (one cause: another build).
    const Record* first_wrong_hash = nullptr;
    std::string first_wrong_hash_message;
    int wrong_hashes = 0;
    for (const TrialRecord* t : unique) {
        const Record& r = *t->record;
        const int position = t->trial.position;
        if (position != expected) {
            problems.add(r.file, r.line, r.column, r.field("position"),
                         fmt::format("subject {}: expected trial {} next in plan order, got trial {} (answers out "
                                     "of plan order or missing; the study answers trials in order and resumes "
                                     "at the first unanswered one)",
                                     subject, expected, position));
            break;
        }
        ++expected;
        if (position > static_cast<int>(plan.size())) {
            problems.add(r.file, r.line, r.column, r.field("position"),
                         fmt::format("subject {} has {} planned trials, got trial {}", subject, plan.size(), position));
            break;
        }
        const PlannedTrial& planned = plan[static_cast<std::size_t>(position - 1)];
        if (!(t->trial == planned)) {
            problems.add(r.file, r.line, r.column, r.field("trial"),
                         fmt::format("subject {} trial {} is {} {} list {} {} in the results, the design of {} has "
                                     "{} {} list {} {} (results of another export or design?)",
                                     subject, position, to_string(t->trial.phase), t->trial.condition,
                                     t->trial.list, t->trial.sentence, settings.protocol.string(),
                                     to_string(planned.phase), planned.condition, planned.list, planned.sentence));
            continue;
        }
        const auto entry = manifest.stimuli.find(planned.stimulus);
        if (entry == manifest.stimuli.end())
            problems.add(r.file, r.line, r.column, r.field("stimulus"),
                         fmt::format("{} is not in {}", planned.stimulus,
                                     (settings.stimuli / "manifest.json").string()));
        else if (entry->second.sha256 != t->stimulus_sha256 && ++wrong_hashes == 1) {
            first_wrong_hash = &r;
            first_wrong_hash_message = fmt::format("expected {} ({} in the manifest), got {}: the participant saw "
                                                   "another file",
                                                   entry->second.sha256, planned.stimulus, t->stimulus_sha256);
        }
        if (!t->session.empty() && !s.sessions.count(t->session))
            problems.add(r.file, r.line, r.column, r.field("session"),
                         fmt::format("browser session {} has trials but no session record: part of the results "
                                     "is missing (give every results file)",
                                     t->session));
    }
    if (first_wrong_hash)
        problems.add(first_wrong_hash->file, first_wrong_hash->line, first_wrong_hash->column,
                     first_wrong_hash->field("stimulus_sha256"),
                     wrong_hashes == 1
                         ? first_wrong_hash_message
                         : fmt::format("{} (and {} more of subject {}'s trials: {} in all with a stimulus hash "
                                       "not in {}; results of another stimulus build?)",
                                       first_wrong_hash_message, wrong_hashes - 1, subject, wrong_hashes,
                                       (settings.stimuli / "manifest.json").string()));
}

// A checked subject as the store imports it: its browser sessions in time
// order, each with its trials and checks; notes its completeness.
OnlineSubject online_subject(int subject, const std::vector<PlannedTrial>& plan, SubjectRecords& s,
                             const std::vector<TrialRecord*>& unique, ImportWebResult& result) {
    OnlineSubject o;
    o.subject = subject;
    o.plan = plan;
    std::map<std::string, std::size_t> session_index;
    std::vector<std::pair<std::string, SessionRecord>> chronological(s.sessions.begin(), s.sessions.end());
    std::stable_sort(chronological.begin(), chronological.end(),
                     [](const auto& a, const auto& b) { return a.second.time_utc < b.second.time_utc; });
    for (const auto& [id, sr] : chronological) {
        OnlineSession os;
        os.external_id = id;
        os.started_utc = sr.time_utc;
        os.ended_utc = s.last_time[id];
        os.details = sr.details;
        os.first_position = sr.first_position;
        os.end_reason = "incomplete";
        os.screening_trials = s.screening_trials[id];
        os.screening = s.screening[id];
        os.events = s.events[id];
        for (const auto& r : os.screening)
            if (!r.passed) ++result.screening_failed;
        session_index[id] = o.sessions.size();
        o.sessions.push_back(std::move(os));
    }
    for (const TrialRecord* t : unique) {
        OnlineSession::Trial trial{t->trial,
                                   t->presentation,
                                   t->web,
                                   t->response,
                                   t->answered_utc,
                                   t->record->file,
                                   t->record->line,
                                   t->record->column};
        OnlineSession& os = o.sessions[session_index.at(t->session)];
        if (t->trial.position == static_cast<int>(plan.size())) os.end_reason = "completed";
        os.trials.push_back(std::move(trial));
    }
    const int answered = static_cast<int>(unique.size());
    std::string screening_note;
    for (const auto& os : o.sessions)
        for (const auto& r : os.screening)
            screening_note += fmt::format(", {} {}/{} {}", r.test, r.correct, r.trials, r.passed ? "passed" : "FAILED");
    result.notes.push_back(fmt::format("subject {}: {} of {} trials answered{}, {} browser session(s){}", subject,
                                       answered, plan.size(), answered == static_cast<int>(plan.size()) ? " (complete)" : "",
                                       o.sessions.size(), screening_note));
    if (answered < static_cast<int>(plan.size()))
        result.incomplete.push_back({subject, answered, static_cast<int>(plan.size())});
    return o;
}

// Stores the subjects in the database (the same experiment, everything in
// one transaction) and sets the result's counts and timing certificates.
void store_online(const ImportWebSettings& settings, const Protocol& protocol, const std::vector<OnlineSubject>& online,
                  ImportWebResult& result) {
    Store store(settings.database);
    if (const auto name = store.meta("experiment"); name && *name != protocol.name)
        throw InputError(settings.database, fmt::format("this database belongs to experiment \"{}\", the protocol is "
                                                        "\"{}\"; give another --db",
                                                        *name, protocol.name));
    std::string sources;
    for (const auto& p : settings.results) sources += (sources.empty() ? "" : ", ") + p.filename().string();
    const OnlineImportCounts counts = store.import_online(online, "imported from " + sources);
    if (!store.meta("experiment")) {
        store.set_meta("experiment", protocol.name);
        store.set_meta("protocol_sha256", sha256_file(settings.protocol));
    }
    result.subjects_added = counts.subjects_added;
    result.sessions_added = counts.sessions_added;
    result.trials_added = counts.trials_added;
    result.trials_present = counts.trials_present;
    std::set<int> imported;
    for (const auto& o : online) imported.insert(o.subject);
    for (auto& c : timing_certificates(store))
        if (imported.count(c.subject)) result.timing.push_back(std::move(c));
}

}  // namespace

ImportWebResult import_web(const ImportWebSettings& settings) {
    if (settings.results.empty()) throw UsageError("give at least one results file");
    const Protocol protocol = load_protocol(settings.protocol);
    const Corpus corpus = read_corpus(protocol.corpus.sentences);
    const ListAssignment assignment = assign_lists(corpus, protocol.design);
    if (settings.stimuli.empty())
        throw UsageError("--stimuli: give the stimulus folder (or the exported study folder) whose manifest.json "
                         "the study was exported from; the trials' stimulus hashes are checked against it");
    const StimulusManifest manifest = read_stimulus_manifest(settings.stimuli);

    ImportWebResult result;
    const std::vector<Record> records = read_records(settings, result);
    DiagnosticList problems;
    auto subject_runs = collect_runs(records, protocol, result, problems);
    problems.throw_if_any();
    std::map<int, SubjectRecords> subjects = choose_runs(subject_runs, settings.runs, result, problems);
    problems.throw_if_any();
    // Each subject against the design: plan order, lists, stimulus hashes.
    std::vector<OnlineSubject> online;
    for (auto& [subject, s] : subjects) {
        const std::vector<PlannedTrial> plan = design_subject(protocol, assignment, subject);
        const std::vector<TrialRecord*> unique = unique_trials(s, subject, result, problems);
        check_against_design(settings, manifest, plan, s, unique, subject, problems);
        if (!problems.empty()) continue;
        online.push_back(online_subject(subject, plan, s, unique, result));
    }
    problems.throw_if_any();
    result.subjects = static_cast<int>(online.size());
    if (settings.require_complete && !result.incomplete.empty()) {
        std::string list;
        for (const auto& i : result.incomplete)
            list += fmt::format("{}subject {} ({} of {})", list.empty() ? "" : ", ", i.subject, i.answered, i.planned);
        throw InputError(settings.results.front(),
                         fmt::format("--require-complete: {} subject{} with fewer trials than the design: {}; nothing was "
                                     "imported",
                                     result.incomplete.size(), result.incomplete.size() == 1 ? "" : "s", list));
    }
    store_online(settings, protocol, online, result);
    return result;
}

}  // namespace avsi::experiment
