// SQLite session store and CSV export (see store.h).
#include "avsi/experiment/store.h"

#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <ctime>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::experiment {

namespace {

// One prepared statement; binds by 1-based index and steps.
class Statement {
public:
    Statement(sqlite3* db, const std::string& sql) : m_db(db) {
        if (sqlite3_prepare_v2(db, sql.c_str(), -1, &m_stmt, nullptr) != SQLITE_OK)
            throw std::runtime_error(fmt::format("SQLite: {} in: {}", sqlite3_errmsg(db), sql));
    }
    ~Statement() { sqlite3_finalize(m_stmt); }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;

    Statement& bind(int i, int v) { return check(sqlite3_bind_int(m_stmt, i, v)); }
    Statement& bind(int i, double v) { return check(sqlite3_bind_double(m_stmt, i, v)); }
    Statement& bind(int i, const std::string& v) {
        return check(sqlite3_bind_text(m_stmt, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    }
    // True while a row is available.
    bool step() {
        const int rc = sqlite3_step(m_stmt);
        if (rc == SQLITE_ROW) return true;
        if (rc == SQLITE_DONE) return false;
        throw std::runtime_error(fmt::format("SQLite: {}", sqlite3_errmsg(m_db)));
    }
    void run() {
        while (step()) {
        }
    }
    int integer(int c) const { return sqlite3_column_int(m_stmt, c); }
    double real(int c) const { return sqlite3_column_double(m_stmt, c); }
    std::string text(int c) const {
        const auto* p = sqlite3_column_text(m_stmt, c);
        return p ? std::string(reinterpret_cast<const char*>(p)) : std::string();
    }
    bool null(int c) const { return sqlite3_column_type(m_stmt, c) == SQLITE_NULL; }

private:
    Statement& check(int rc) {
        if (rc != SQLITE_OK) throw std::runtime_error(fmt::format("SQLite: {}", sqlite3_errmsg(m_db)));
        return *this;
    }
    sqlite3* m_db;
    sqlite3_stmt* m_stmt = nullptr;
};

// Runs a transaction; rolls back if not committed.
class Transaction {
public:
    explicit Transaction(sqlite3* db) : m_db(db) { exec("BEGIN IMMEDIATE"); }
    ~Transaction() {
        if (!m_done) sqlite3_exec(m_db, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
        exec("COMMIT");
        m_done = true;
    }

private:
    void exec(const char* sql) {
        char* error = nullptr;
        if (sqlite3_exec(m_db, sql, nullptr, nullptr, &error) != SQLITE_OK) {
            std::string message = error ? error : "unknown";
            sqlite3_free(error);
            throw std::runtime_error("SQLite: " + message);
        }
    }
    sqlite3* m_db;
    bool m_done = false;
};

const char* schema_v1 = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE subjects(subject INTEGER PRIMARY KEY, created_utc TEXT NOT NULL);
CREATE TABLE sessions(
  session INTEGER PRIMARY KEY AUTOINCREMENT,
  subject INTEGER NOT NULL REFERENCES subjects(subject),
  started_utc TEXT NOT NULL,
  ended_utc TEXT,
  end_reason TEXT,
  first_position INTEGER NOT NULL,
  details TEXT NOT NULL DEFAULT '');
CREATE TABLE planned_trials(
  subject INTEGER NOT NULL REFERENCES subjects(subject),
  position INTEGER NOT NULL,
  phase TEXT NOT NULL,
  block INTEGER NOT NULL,
  list TEXT NOT NULL,
  condition TEXT NOT NULL,
  sentence TEXT NOT NULL,
  stimulus TEXT NOT NULL,
  PRIMARY KEY(subject, position));
CREATE TABLE presentations(
  subject INTEGER NOT NULL,
  position INTEGER NOT NULL,
  session INTEGER NOT NULL REFERENCES sessions(session),
  audio_onset_s REAL, video_onset_s REAL, duration_s REAL, refresh_hz REAL,
  frames_total INTEGER, frames_shown INTEGER, dropped_frames INTEGER, repeated_frames INTEGER,
  mean_offset_ms REAL, max_abs_offset_ms REAL,
  PRIMARY KEY(subject, position),
  FOREIGN KEY(subject, position) REFERENCES planned_trials(subject, position));
CREATE TABLE frames(
  subject INTEGER NOT NULL, position INTEGER NOT NULL, frame INTEGER NOT NULL,
  pts_s REAL NOT NULL, flip_s REAL NOT NULL, offset_ms REAL NOT NULL,
  PRIMARY KEY(subject, position, frame));
CREATE TABLE responses(
  subject INTEGER NOT NULL,
  position INTEGER NOT NULL,
  session INTEGER NOT NULL REFERENCES sessions(session),
  response TEXT NOT NULL,
  response_time_ms REAL NOT NULL,
  confirmed_empty INTEGER NOT NULL,
  answered_utc TEXT NOT NULL,
  PRIMARY KEY(subject, position),
  FOREIGN KEY(subject, position) REFERENCES planned_trials(subject, position));
CREATE TABLE events(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  session INTEGER, subject INTEGER, time_utc TEXT NOT NULL, kind TEXT NOT NULL, detail TEXT NOT NULL);
)sql";

}  // namespace

std::string utc_now() {
    const auto now = std::chrono::system_clock::now();
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count();
    const std::time_t t = static_cast<std::time_t>(ms / 1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", tm.tm_year + 1900, tm.tm_mon + 1,
                       tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms % 1000);
}

Store::Store(const std::filesystem::path& path) : m_path(path) {
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
    if (sqlite3_open_v2(path.c_str(), &m_db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
        const std::string message = m_db ? sqlite3_errmsg(m_db) : "out of memory";
        sqlite3_close(m_db);
        m_db = nullptr;
        throw InputError(path, "cannot open the session database: " + message);
    }
    sqlite3_busy_timeout(m_db, 5000);
    try {
        int version = 0;
        {
            Statement s(m_db, "PRAGMA user_version");
            if (s.step()) version = s.integer(0);
        }
        if (version > store_schema_version)
            throw InputError(path, fmt::format("the session database has schema version {}, newer than "
                                               "this avsi supports ({}); use a newer avsi",
                                               version, store_schema_version));
        exec("PRAGMA journal_mode=WAL");
        exec("PRAGMA synchronous=FULL");
        exec("PRAGMA foreign_keys=ON");
        if (version == 0) {
            // Create the schema under a write lock, checking again inside it:
            // another process may have created it meanwhile.
            Transaction tx(m_db);
            int current = 0, tables = 0;
            {
                Statement again(m_db, "PRAGMA user_version");
                if (again.step()) current = again.integer(0);
                Statement count(m_db, "SELECT count(*) FROM sqlite_master WHERE type='table'");
                if (count.step()) tables = count.integer(0);
            }
            if (current == 0) {
                if (tables != 0)
                    throw InputError(path, "not an avsi session database (it has tables but no avsi schema version)");
                exec(schema_v1);
                exec(fmt::format("PRAGMA user_version={}", store_schema_version));
            }
            tx.commit();
        }
    } catch (const InputError&) {
        sqlite3_close(m_db);
        m_db = nullptr;
        throw;
    } catch (const std::exception& e) {
        sqlite3_close(m_db);
        m_db = nullptr;
        throw InputError(path, std::string("cannot use the session database: ") + e.what());
    }
}

Store::~Store() {
    if (m_db) sqlite3_close(m_db);
}

void Store::exec(const std::string& sql) const {
    char* error = nullptr;
    if (sqlite3_exec(m_db, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
        std::string message = error ? error : "unknown";
        sqlite3_free(error);
        throw std::runtime_error("SQLite: " + message);
    }
}

int Store::schema_version() const {
    Statement s(m_db, "PRAGMA user_version");
    return s.step() ? s.integer(0) : 0;
}

void Store::set_meta(const std::string& key, const std::string& value) {
    Statement(m_db, "INSERT OR REPLACE INTO meta(key, value) VALUES(?, ?)").bind(1, key).bind(2, value).run();
}

std::optional<std::string> Store::meta(const std::string& key) const {
    Statement s(m_db, "SELECT value FROM meta WHERE key = ?");
    s.bind(1, key);
    if (s.step()) return s.text(0);
    return std::nullopt;
}

std::vector<PlannedTrial> Store::planned_trials(int subject) const {
    Statement s(m_db,
                "SELECT position, phase, block, list, condition, sentence, stimulus FROM planned_trials "
                "WHERE subject = ? ORDER BY position");
    s.bind(1, subject);
    std::vector<PlannedTrial> out;
    while (s.step()) {
        PlannedTrial t;
        t.subject = subject;
        t.position = s.integer(0);
        if (!parse_phase(s.text(1), t.phase))
            throw InputError(m_path, fmt::format("planned trial {} of subject {} has an unknown phase \"{}\"",
                                                 t.position, subject, s.text(1)));
        t.block = s.integer(2);
        t.list = s.text(3);
        t.condition = s.text(4);
        t.sentence = s.text(5);
        t.stimulus = s.text(6);
        out.push_back(std::move(t));
    }
    return out;
}

void Store::add_subject(int subject, const std::vector<PlannedTrial>& trials) {
    Transaction tx(m_db);
    Statement(m_db, "INSERT INTO subjects(subject, created_utc) VALUES(?, ?)").bind(1, subject).bind(2, utc_now()).run();
    for (const auto& t : trials) {
        AVSI_ASSERT(t.subject == subject);
        Statement s(m_db,
                    "INSERT INTO planned_trials(subject, position, phase, block, list, condition, sentence, "
                    "stimulus) VALUES(?, ?, ?, ?, ?, ?, ?, ?)");
        s.bind(1, subject).bind(2, t.position).bind(3, to_string(t.phase)).bind(4, t.block);
        s.bind(5, t.list).bind(6, t.condition).bind(7, t.sentence).bind(8, t.stimulus);
        s.run();
    }
    tx.commit();
}

std::vector<int> Store::answered_positions(int subject) const {
    Statement s(m_db, "SELECT position FROM responses WHERE subject = ? ORDER BY position");
    s.bind(1, subject);
    std::vector<int> out;
    while (s.step()) out.push_back(s.integer(0));
    return out;
}

namespace {
std::vector<SessionInfo> read_sessions(sqlite3* db, const std::string& where, int subject) {
    Statement s(db, "SELECT session, subject, started_utc, ended_utc, end_reason, first_position FROM sessions "
                    "WHERE subject = ? " + where + " ORDER BY session");
    s.bind(1, subject);
    std::vector<SessionInfo> out;
    while (s.step()) {
        SessionInfo i;
        i.session = s.integer(0);
        i.subject = s.integer(1);
        i.started_utc = s.text(2);
        i.ended_utc = s.text(3);
        i.end_reason = s.text(4);
        i.first_position = s.integer(5);
        out.push_back(std::move(i));
    }
    return out;
}
}  // namespace

std::vector<SessionInfo> Store::open_sessions(int subject) const {
    return read_sessions(m_db, "AND end_reason IS NULL", subject);
}

std::vector<SessionInfo> Store::sessions(int subject) const { return read_sessions(m_db, "", subject); }

int Store::begin_session(int subject, int first_position, const std::string& details) {
    Statement(m_db, "INSERT INTO sessions(subject, started_utc, first_position, details) VALUES(?, ?, ?, ?)")
        .bind(1, subject).bind(2, utc_now()).bind(3, first_position).bind(4, details).run();
    return static_cast<int>(sqlite3_last_insert_rowid(m_db));
}

void Store::end_session(int session, const std::string& reason) {
    Statement(m_db, "UPDATE sessions SET ended_utc = ?, end_reason = ? WHERE session = ?")
        .bind(1, utc_now()).bind(2, reason).bind(3, session).run();
}

void Store::mark_interrupted(int session) {
    Statement(m_db, "UPDATE sessions SET end_reason = 'interrupted' WHERE session = ? AND end_reason IS NULL")
        .bind(1, session).run();
}

void Store::add_event(int session, int subject, const std::string& kind, const std::string& detail) {
    Statement(m_db, "INSERT INTO events(session, subject, time_utc, kind, detail) VALUES(?, ?, ?, ?, ?)")
        .bind(1, session).bind(2, subject).bind(3, utc_now()).bind(4, kind).bind(5, detail).run();
}

void Store::commit_trial(int session, const PlannedTrial& trial, const Presentation& p, const Response& r) {
    Transaction tx(m_db);
    {
        Statement check(m_db, "SELECT count(*) FROM responses WHERE subject = ? AND position = ?");
        check.bind(1, trial.subject).bind(2, trial.position);
        check.step();
        if (check.integer(0) != 0)
            throw std::runtime_error(fmt::format("trial {} of subject {} already has a response",
                                                 trial.position, trial.subject));
    }
    Statement(m_db, "DELETE FROM presentations WHERE subject = ? AND position = ?")
        .bind(1, trial.subject).bind(2, trial.position).run();
    Statement(m_db, "DELETE FROM frames WHERE subject = ? AND position = ?")
        .bind(1, trial.subject).bind(2, trial.position).run();
    Statement pres(m_db,
                   "INSERT INTO presentations(subject, position, session, audio_onset_s, video_onset_s, "
                   "duration_s, refresh_hz, frames_total, frames_shown, dropped_frames, repeated_frames, "
                   "mean_offset_ms, max_abs_offset_ms) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    pres.bind(1, trial.subject).bind(2, trial.position).bind(3, session).bind(4, p.audio_onset_s);
    pres.bind(5, p.video_onset_s).bind(6, p.duration_s).bind(7, p.refresh_hz).bind(8, p.frames_total);
    pres.bind(9, p.frames_shown).bind(10, p.dropped_frames).bind(11, p.repeated_frames);
    pres.bind(12, p.mean_offset_ms).bind(13, p.max_abs_offset_ms);
    pres.run();
    for (const auto& f : p.flips) {
        Statement s(m_db, "INSERT INTO frames(subject, position, frame, pts_s, flip_s, offset_ms) VALUES(?, ?, ?, ?, ?, ?)");
        s.bind(1, trial.subject).bind(2, trial.position).bind(3, f.frame).bind(4, f.pts_s).bind(5, f.flip_s);
        s.bind(6, f.offset_ms);
        s.run();
    }
    Statement resp(m_db,
                   "INSERT INTO responses(subject, position, session, response, response_time_ms, "
                   "confirmed_empty, answered_utc) VALUES(?, ?, ?, ?, ?, ?, ?)");
    resp.bind(1, trial.subject).bind(2, trial.position).bind(3, session).bind(4, r.text);
    resp.bind(5, r.response_time_ms).bind(6, r.confirmed_empty ? 1 : 0).bind(7, utc_now());
    resp.run();
    tx.commit();
}

std::vector<ResponseRow> Store::responses() const {
    Statement s(m_db,
                "SELECT p.subject, p.position, p.phase, p.block, p.list, p.condition, p.sentence, p.stimulus, "
                "r.session, r.response, r.response_time_ms, r.confirmed_empty, r.answered_utc "
                "FROM responses r JOIN planned_trials p ON p.subject = r.subject AND p.position = r.position "
                "ORDER BY p.subject, p.position");
    std::vector<ResponseRow> out;
    while (s.step()) {
        ResponseRow row;
        row.trial.subject = s.integer(0);
        row.trial.position = s.integer(1);
        parse_phase(s.text(2), row.trial.phase);
        row.trial.block = s.integer(3);
        row.trial.list = s.text(4);
        row.trial.condition = s.text(5);
        row.trial.sentence = s.text(6);
        row.trial.stimulus = s.text(7);
        row.session = s.integer(8);
        row.response.text = s.text(9);
        row.response.response_time_ms = s.real(10);
        row.response.confirmed_empty = s.integer(11) != 0;
        row.answered_utc = s.text(12);
        out.push_back(std::move(row));
    }
    return out;
}

std::vector<Store::TimingRow> Store::timing(bool with_frames) const {
    Statement s(m_db,
                "SELECT subject, position, session, audio_onset_s, video_onset_s, duration_s, refresh_hz, "
                "frames_total, frames_shown, dropped_frames, repeated_frames, mean_offset_ms, max_abs_offset_ms "
                "FROM presentations ORDER BY subject, position");
    std::vector<TimingRow> out;
    while (s.step()) {
        TimingRow row;
        row.subject = s.integer(0);
        row.position = s.integer(1);
        row.session = s.integer(2);
        Presentation& p = row.presentation;
        p.audio_onset_s = s.real(3);
        p.video_onset_s = s.real(4);
        p.duration_s = s.real(5);
        p.refresh_hz = s.real(6);
        p.frames_total = s.integer(7);
        p.frames_shown = s.integer(8);
        p.dropped_frames = s.integer(9);
        p.repeated_frames = s.integer(10);
        p.mean_offset_ms = s.real(11);
        p.max_abs_offset_ms = s.real(12);
        if (with_frames) {
            Statement f(m_db, "SELECT frame, pts_s, flip_s, offset_ms FROM frames WHERE subject = ? AND "
                              "position = ? ORDER BY frame");
            f.bind(1, row.subject).bind(2, row.position);
            while (f.step()) p.flips.push_back({f.integer(0), f.real(1), f.real(2), f.real(3)});
        }
        out.push_back(std::move(row));
    }
    return out;
}

std::vector<Store::EventRow> Store::events() const {
    Statement s(m_db, "SELECT session, subject, time_utc, kind, detail FROM events ORDER BY id");
    std::vector<EventRow> out;
    while (s.step()) out.push_back({s.integer(0), s.integer(1), s.text(2), s.text(3), s.text(4)});
    return out;
}

std::vector<int> Store::subjects() const {
    Statement s(m_db, "SELECT subject FROM subjects ORDER BY subject");
    std::vector<int> out;
    while (s.step()) out.push_back(s.integer(0));
    return out;
}

std::vector<std::filesystem::path> export_store(const Store& store, const std::filesystem::path& out_dir) {
    std::vector<std::filesystem::path> written;
    auto num = [](double v) { return fmt::format("{:.6f}", v); };
    auto ms = [](double v) { return fmt::format("{:.3f}", v); };

    // responses.csv: the analysis input columns first, then extras.
    std::string responses = csv_line({"subject", "session", "trial", "phase", "condition", "list", "sentence",
                                      "response", "response_time_ms", "block", "stimulus", "confirmed_empty",
                                      "answered_utc"});
    for (const auto& r : store.responses())
        responses += csv_line({std::to_string(r.trial.subject), std::to_string(r.session),
                               std::to_string(r.trial.position), to_string(r.trial.phase), r.trial.condition,
                               r.trial.list, r.trial.sentence, r.response.text, ms(r.response.response_time_ms),
                               std::to_string(r.trial.block), r.trial.stimulus,
                               r.response.confirmed_empty ? "1" : "0", r.answered_utc});
    written.push_back(out_dir / "responses.csv");
    write_text_file(written.back(), responses);

    const auto timing = store.timing(true);
    std::string timing_csv = csv_line({"subject", "session", "trial", "audio_onset_s", "video_onset_s", "duration_s",
                                       "refresh_hz", "frames_total", "frames_shown", "dropped_frames",
                                       "repeated_frames", "mean_av_offset_ms", "max_abs_av_offset_ms"});
    std::string frames_csv = csv_line({"subject", "trial", "frame", "pts_s", "flip_s", "av_offset_ms"});
    for (const auto& t : timing) {
        const Presentation& p = t.presentation;
        timing_csv += csv_line({std::to_string(t.subject), std::to_string(t.session), std::to_string(t.position),
                                num(p.audio_onset_s), num(p.video_onset_s), num(p.duration_s), num(p.refresh_hz),
                                std::to_string(p.frames_total), std::to_string(p.frames_shown),
                                std::to_string(p.dropped_frames), std::to_string(p.repeated_frames),
                                ms(p.mean_offset_ms), ms(p.max_abs_offset_ms)});
        for (const auto& f : p.flips)
            frames_csv += csv_line({std::to_string(t.subject), std::to_string(t.position), std::to_string(f.frame),
                                    num(f.pts_s), num(f.flip_s), ms(f.offset_ms)});
    }
    // One summary row per session: what a methods section reports.
    struct Summary {
        int subject = 0, presentations = 0, frames = 0, dropped = 0, repeated = 0;
        double sum_offset_ms = 0.0, max_abs_offset_ms = 0.0;
        int offsets = 0;
    };
    std::map<int, Summary> summaries;
    for (const auto& t : timing) {
        Summary& s = summaries[t.session];
        s.subject = t.subject;
        ++s.presentations;
        s.frames += t.presentation.frames_total;
        s.dropped += t.presentation.dropped_frames;
        s.repeated += t.presentation.repeated_frames;
        s.max_abs_offset_ms = std::max(s.max_abs_offset_ms, t.presentation.max_abs_offset_ms);
        for (const auto& f : t.presentation.flips) {
            s.sum_offset_ms += f.offset_ms;
            ++s.offsets;
        }
    }
    std::string summary_csv = csv_line({"subject", "session", "presentations", "frames", "dropped_frames",
                                        "repeated_frames", "mean_av_offset_ms", "max_abs_av_offset_ms"});
    for (const auto& [session, s] : summaries)
        summary_csv += csv_line({std::to_string(s.subject), std::to_string(session), std::to_string(s.presentations),
                                 std::to_string(s.frames), std::to_string(s.dropped), std::to_string(s.repeated),
                                 ms(s.offsets ? s.sum_offset_ms / s.offsets : 0.0), ms(s.max_abs_offset_ms)});
    written.push_back(out_dir / "timing_summary.csv");
    write_text_file(written.back(), summary_csv);
    written.push_back(out_dir / "timing.csv");
    write_text_file(written.back(), timing_csv);
    written.push_back(out_dir / "frames.csv");
    write_text_file(written.back(), frames_csv);

    std::string sessions_csv =
        csv_line({"subject", "session", "started_utc", "ended_utc", "end_reason", "first_trial"});
    for (int subject : store.subjects())
        for (const auto& s : store.sessions(subject))
            sessions_csv += csv_line({std::to_string(s.subject), std::to_string(s.session), s.started_utc,
                                      s.ended_utc, s.end_reason.empty() ? "open" : s.end_reason,
                                      std::to_string(s.first_position)});
    written.push_back(out_dir / "sessions.csv");
    write_text_file(written.back(), sessions_csv);

    std::string events_csv = csv_line({"session", "subject", "time_utc", "kind", "detail"});
    for (const auto& e : store.events())
        events_csv += csv_line({std::to_string(e.session), std::to_string(e.subject), e.time_utc, e.kind, e.detail});
    written.push_back(out_dir / "events.csv");
    write_text_file(written.back(), events_csv);
    return written;
}

}  // namespace avsi::experiment
