// SQLite session store and CSV export (see store.h).
#include "avsi/experiment/store.h"
#include "avsi/experiment/timing_certificate.h"

#include <sqlite3.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include <algorithm>
#include <chrono>
#include <concepts>
#include <map>
#include <ctime>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::experiment {

namespace {

// A failed SQLite call as an InputError naming the database and a cause a lab
// can act on (disk full, read-only, damaged, locked), with SQLite's text.
[[noreturn]] void throw_sqlite(sqlite3* db, const std::string& detail = {}) {
    const int code = sqlite3_extended_errcode(db);
    const int errno_value = sqlite3_system_errno(db);
    const char* name = sqlite3_db_filename(db, "main");
    const std::filesystem::path path = name && *name ? name : "<session database>";
    std::string cause;
    switch (code & 0xff) {
        case SQLITE_FULL: cause = "disk full: no space left for the session database"; break;
        case SQLITE_READONLY: cause = "read-only: the database, its folder or the disk cannot be written"; break;
        case SQLITE_CORRUPT:
        case SQLITE_NOTADB: cause = "the file is damaged or not an SQLite database"; break;
        case SQLITE_BUSY:
        case SQLITE_LOCKED: cause = "another process holds the database locked"; break;
        case SQLITE_CANTOPEN: cause = "cannot open the database or its journal (folder missing or read-only?)"; break;
        case SQLITE_IOERR:
            if (errno_value == ENOSPC || errno_value == EDQUOT || errno_value == EFBIG)
                cause = "disk full: no space left for the session database";
            else if (errno_value == EROFS || errno_value == EACCES || errno_value == EPERM)
                cause = "read-only: the database, its folder or the disk cannot be written";
            else
                cause = "input/output error";
            break;
        default: cause = "not a usable avsi session database"; break;
    }
    std::string message = fmt::format("{} (SQLite: {}", cause, sqlite3_errmsg(db));
    if (errno_value != 0 && (code & 0xff) != SQLITE_ERROR) message += fmt::format("; {}", std::strerror(errno_value));
    message += detail.empty() ? ")" : "; " + detail + ")";
    throw InputError(path, message);
}

class Statement;

// A row of a result read in the SELECT's column order: each call maps the
// next column, so a row's mapping reads as the list of its fields, with no
// column numbers to keep in step with the SELECT.
class Columns {
public:
    explicit Columns(const Statement& s) : m_s(s) {}
    int integer();
    double real();
    std::string text();
    bool flag() { return integer() != 0; }  // a 0/1 column

private:
    const Statement& m_s;
    int m_next = 0;
};

// One prepared statement; binds by 1-based index (or all of a row's values
// in order, bind_row) and steps.
class Statement {
public:
    Statement(sqlite3* db, const std::string& sql) : m_db(db) {
        if (sqlite3_prepare_v2(db, sql.c_str(), -1, &m_stmt, nullptr) != SQLITE_OK)
            throw_sqlite(db, sql.size() > 60 ? sql.substr(0, 60) + "…" : sql);
    }
    ~Statement() { sqlite3_finalize(m_stmt); }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;

    Statement& bind(int i, int v) { return check(sqlite3_bind_int(m_stmt, i, v)); }
    Statement& bind(int i, double v) { return check(sqlite3_bind_double(m_stmt, i, v)); }
    Statement& bind(int i, const std::string& v) {
        return check(sqlite3_bind_text(m_stmt, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    }
    // A bool as 0/1 (a bool only: a string literal must not become one).
    template <std::same_as<bool> B>
    Statement& bind(int i, B v) {
        return bind(i, v ? 1 : 0);
    }
    // Binds the values to ?1, ?2, … in the order given (the column list's).
    template <typename... Values>
    Statement& bind_row(const Values&... values) {
        int i = 0;
        (bind(++i, values), ...);
        return *this;
    }
    // True while a row is available.
    bool step() {
        const int rc = sqlite3_step(m_stmt);
        if (rc == SQLITE_ROW) return true;
        if (rc == SQLITE_DONE) return false;
        throw_sqlite(m_db);
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
    sqlite3_stmt* handle() const { return m_stmt; }

private:
    Statement& check(int rc) {
        if (rc != SQLITE_OK) throw_sqlite(m_db);
        return *this;
    }
    sqlite3* m_db;
    sqlite3_stmt* m_stmt = nullptr;
};

int Columns::integer() { return m_s.integer(m_next++); }
double Columns::real() { return m_s.real(m_next++); }
std::string Columns::text() { return m_s.text(m_next++); }

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
        if (sqlite3_exec(m_db, sql, nullptr, nullptr, nullptr) != SQLITE_OK) throw_sqlite(m_db);
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

// Version 1 → 2: online sessions (avsi import-web).
const char* migration_v2 = R"sql(
ALTER TABLE sessions ADD COLUMN mode TEXT NOT NULL DEFAULT 'lab';
ALTER TABLE sessions ADD COLUMN external_id TEXT;
CREATE TABLE web_presentations(
  subject INTEGER NOT NULL,
  position INTEGER NOT NULL,
  frame_callbacks INTEGER NOT NULL,
  presented_frames INTEGER NOT NULL,
  missed_callbacks INTEGER NOT NULL,
  browser_dropped_frames INTEGER NOT NULL,
  browser_total_frames INTEGER NOT NULL,
  output_latency_ms REAL NOT NULL,
  base_latency_ms REAL NOT NULL,
  audio_path_ms REAL NOT NULL,
  audio_path_measured INTEGER NOT NULL,
  PRIMARY KEY(subject, position),
  FOREIGN KEY(subject, position) REFERENCES planned_trials(subject, position));
CREATE TABLE screening_trials(
  subject INTEGER NOT NULL,
  session INTEGER NOT NULL REFERENCES sessions(session),
  test TEXT NOT NULL,
  trial INTEGER NOT NULL,
  answer INTEGER NOT NULL,
  response INTEGER NOT NULL,
  correct INTEGER NOT NULL,
  response_time_ms REAL NOT NULL,
  PRIMARY KEY(subject, session, test, trial));
CREATE TABLE screening(
  subject INTEGER NOT NULL,
  session INTEGER NOT NULL REFERENCES sessions(session),
  test TEXT NOT NULL,
  trials INTEGER NOT NULL,
  correct INTEGER NOT NULL,
  required INTEGER NOT NULL,
  passed INTEGER NOT NULL,
  PRIMARY KEY(subject, session, test));
)sql";

// Version 2 → 3: adaptive SRT tracks.
const char* migration_v3 = R"sql(
CREATE TABLE adaptive_trials(
  subject INTEGER NOT NULL,
  position INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  session INTEGER NOT NULL REFERENCES sessions(session),
  track TEXT NOT NULL,
  presentation INTEGER NOT NULL,
  sentence_index INTEGER NOT NULL,
  level_db REAL NOT NULL,
  keywords INTEGER NOT NULL,
  correct INTEGER NOT NULL,
  auto_correct INTEGER NOT NULL,
  marks TEXT NOT NULL,
  corrected INTEGER NOT NULL,
  next_level_db REAL NOT NULL,
  step_db REAL NOT NULL,
  reversal INTEGER NOT NULL,
  reversals INTEGER NOT NULL,
  repeat INTEGER NOT NULL,
  at_bound INTEGER NOT NULL,
  speech_gain_db REAL NOT NULL,
  noise_gain_db REAL NOT NULL,
  limit_gain_db REAL NOT NULL,
  response TEXT NOT NULL,
  answered_utc TEXT NOT NULL,
  PRIMARY KEY(subject, position, attempt),
  FOREIGN KEY(subject, position) REFERENCES planned_trials(subject, position));
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
    std::error_code ec;
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
    if (ec) throw InputError(path, fmt::format("cannot create the database's folder: {}", ec.message()));
    // The database and its folder must be writable (WAL puts -wal and -shm
    // files beside it): say so now, before any trial, not at the first commit.
    const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
    for (const auto& [file, what] : {std::pair{path, "the session database"}, std::pair{folder, "its folder"}}) {
        if (std::filesystem::exists(file) && ::access(file.c_str(), W_OK) != 0)
            throw InputError(path, fmt::format("read-only: {} {} cannot be written ({}); avsi writes there (responses, "
                                               "the WAL journal): copy the database to a writable place or fix "
                                               "the permissions",
                                               what, file.string(), std::strerror(errno)));
    }
    if (sqlite3_open_v2(path.c_str(), &m_db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
        if (!m_db) throw InputError(path, "cannot open the session database: out of memory");
        try {
            throw_sqlite(m_db);
        } catch (...) {
            sqlite3_close(m_db);
            m_db = nullptr;
            throw;
        }
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
                exec(migration_v2);
                exec(migration_v3);
                exec(fmt::format("PRAGMA user_version={}", store_schema_version));
            }
            tx.commit();
        } else if (version < store_schema_version) {
            // Migrate an older database in place, in one transaction (checking
            // the version again under the write lock).
            Transaction tx(m_db);
            int current = 0;
            {
                Statement again(m_db, "PRAGMA user_version");
                if (again.step()) current = again.integer(0);
            }
            if (current < 2) exec(migration_v2);
            if (current < 3) exec(migration_v3);
            exec(fmt::format("PRAGMA user_version={}", store_schema_version));
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
    for (const int subject : std::vector<int>(m_locked_subjects)) {
        try {
            unlock_subject(subject);
        } catch (const std::exception&) {
            // A lock that cannot be removed is broken by the next runner.
        }
    }
    if (m_db) sqlite3_close(m_db);
}

namespace {

// What identifies a running process across pid reuse: its start time in
// clock ticks since boot (/proc/<pid>/stat field 22), "" if it is not running.
std::string process_start(long pid) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
    std::string stat;
    if (!in || !std::getline(in, stat)) return {};
    const auto paren = stat.rfind(')');
    if (paren == std::string::npos) return {};
    std::istringstream fields(stat.substr(paren + 1));
    std::string field;
    for (int i = 3; i <= 22 && (fields >> field); ++i) {
    }
    return field;
}

std::string boot_id() {
    std::ifstream in("/proc/sys/kernel/random/boot_id");
    std::string id;
    std::getline(in, id);
    return id;
}

std::string host_name() {
    char name[256] = {};
    if (::gethostname(name, sizeof name - 1) != 0) return "unknown";
    return name;
}

}  // namespace

std::string Store::lock_subject(int subject) {
    Transaction tx(m_db);
    exec("CREATE TABLE IF NOT EXISTS runner_locks(subject INTEGER PRIMARY KEY, pid INTEGER NOT NULL, "
         "host TEXT NOT NULL, boot_id TEXT NOT NULL, process_start TEXT NOT NULL, locked_utc TEXT NOT NULL)");
    const long self = static_cast<long>(::getpid());
    const std::string host = host_name(), boot = boot_id(), start = process_start(self);
    std::string broken;
    {
        Statement held(m_db, "SELECT pid, host, boot_id, process_start, locked_utc FROM runner_locks WHERE subject = ?");
        held.bind(1, subject);
        if (held.step()) {
            const long pid = held.integer(0);
            const std::string holder_host = held.text(1), holder_boot = held.text(2), holder_start = held.text(3),
                              since = held.text(4);
            const bool same_machine = holder_host == host && holder_boot == boot;
            const bool ours = same_machine && pid == self && holder_start == start;
            const bool alive = same_machine && !ours && process_start(pid) == holder_start;
            if (alive || !same_machine) {
                throw InputError(m_path, fmt::format(
                    "subject {} is being run by another runner (process {} on {} since {}){}; one runner per subject: "
                    "wait for it to finish or close it",
                    subject, pid, holder_host, since,
                    same_machine ? "" : fmt::format(" — on another machine, so its lock is kept until that "
                                                    "runner ends or the row of runner_locks is removed")));
            }
            if (!ours)
                broken = fmt::format("a lock left by process {} on {} since {} (no longer running) was broken", pid,
                                     holder_host, since);
        }
    }
    Statement(m_db, "INSERT OR REPLACE INTO runner_locks(subject, pid, host, boot_id, process_start, locked_utc) "
                    "VALUES(?, ?, ?, ?, ?, ?)")
        .bind_row(subject, static_cast<int>(self), host, boot, start, utc_now())
        .run();
    tx.commit();
    if (std::find(m_locked_subjects.begin(), m_locked_subjects.end(), subject) == m_locked_subjects.end())
        m_locked_subjects.push_back(subject);
    return broken;
}

void Store::unlock_subject(int subject) {
    const auto it = std::find(m_locked_subjects.begin(), m_locked_subjects.end(), subject);
    if (it == m_locked_subjects.end()) return;
    m_locked_subjects.erase(it);
    Statement(m_db, "DELETE FROM runner_locks WHERE subject = ? AND pid = ? AND process_start = ?")
        .bind(1, subject).bind(2, static_cast<int>(::getpid())).bind(3, process_start(::getpid())).run();
}

void Store::exec(const std::string& sql) const {
    if (sqlite3_exec(m_db, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) throw_sqlite(m_db);
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
        Columns c(s);
        PlannedTrial t;
        t.subject = subject;
        t.position = c.integer();
        const std::string phase = c.text();
        if (!parse_phase(phase, t.phase))
            throw InputError(m_path, fmt::format("planned trial {} of subject {} has an unknown phase \"{}\"",
                                                 t.position, subject, phase));
        t.block = c.integer();
        t.list = c.text();
        t.condition = c.text();
        t.sentence = c.text();
        t.stimulus = c.text();
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
        s.bind_row(subject, t.position, to_string(t.phase), t.block, t.list, t.condition, t.sentence, t.stimulus);
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
    Statement s(db, "SELECT session, subject, started_utc, ended_utc, end_reason, first_position, mode, "
                    "external_id, details FROM sessions WHERE subject = ? " + where + " ORDER BY session");
    s.bind(1, subject);
    std::vector<SessionInfo> out;
    while (s.step()) {
        Columns c(s);
        SessionInfo i;
        i.session = c.integer();
        i.subject = c.integer();
        i.started_utc = c.text();
        i.ended_utc = c.text();
        i.end_reason = c.text();
        i.first_position = c.integer();
        i.mode = c.text();
        i.external_id = c.text();
        i.details = c.text();
        out.push_back(std::move(i));
    }
    return out;
}
}  // namespace

std::vector<SessionInfo> Store::open_sessions(int subject) const {
    return read_sessions(m_db, "AND end_reason IS NULL AND mode = 'lab'", subject);
}

std::vector<SessionInfo> Store::sessions(int subject) const { return read_sessions(m_db, "", subject); }

int Store::begin_session(int subject, int first_position, const std::string& details) {
    Statement(m_db, "INSERT INTO sessions(subject, started_utc, first_position, details) VALUES(?, ?, ?, ?)")
        .bind_row(subject, utc_now(), first_position, details).run();
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
        .bind_row(session, subject, utc_now(), kind, detail).run();
}

namespace {

// The presentation, frames and response rows of one trial (inside the caller's transaction).
void insert_trial(sqlite3* db, int session, const PlannedTrial& trial, const Presentation& p, const Response& r,
                  const std::string& answered_utc) {
    Statement(db, "DELETE FROM presentations WHERE subject = ? AND position = ?")
        .bind(1, trial.subject).bind(2, trial.position).run();
    Statement(db, "DELETE FROM frames WHERE subject = ? AND position = ?")
        .bind(1, trial.subject).bind(2, trial.position).run();
    Statement pres(db,
                   "INSERT INTO presentations(subject, position, session, audio_onset_s, video_onset_s, "
                   "duration_s, refresh_hz, frames_total, frames_shown, dropped_frames, repeated_frames, "
                   "mean_offset_ms, max_abs_offset_ms) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    pres.bind_row(trial.subject, trial.position, session, p.audio_onset_s, p.video_onset_s, p.duration_s,
                  p.refresh_hz, p.frames_total, p.frames_shown, p.dropped_frames, p.repeated_frames,
                  p.mean_offset_ms, p.max_abs_offset_ms);
    pres.run();
    Statement frame(db, "INSERT INTO frames(subject, position, frame, pts_s, flip_s, offset_ms) VALUES(?, ?, ?, ?, ?, ?)");
    for (const auto& f : p.flips) {
        sqlite3_reset(frame.handle());
        frame.bind_row(trial.subject, trial.position, f.frame, f.pts_s, f.flip_s, f.offset_ms);
        frame.run();
    }
    Statement resp(db,
                   "INSERT INTO responses(subject, position, session, response, response_time_ms, "
                   "confirmed_empty, answered_utc) VALUES(?, ?, ?, ?, ?, ?, ?)");
    resp.bind_row(trial.subject, trial.position, session, r.text, r.response_time_ms, r.confirmed_empty,
                  answered_utc);
    resp.run();
}

}  // namespace

namespace {

void check_unanswered(sqlite3* db, const PlannedTrial& trial) {
    Statement check(db, "SELECT count(*) FROM responses WHERE subject = ? AND position = ?");
    check.bind(1, trial.subject).bind(2, trial.position);
    check.step();
    if (check.integer(0) != 0)
        throw std::runtime_error(fmt::format("trial {} of subject {} already has a response", trial.position,
                                             trial.subject));
}

void insert_adaptive(sqlite3* db, int session, const PlannedTrial& trial, const AdaptiveRecord& a,
                     const std::string& answered_utc) {
    Statement s(db,
                "INSERT INTO adaptive_trials(subject, position, attempt, session, track, presentation, sentence_index, "
                "level_db, keywords, correct, auto_correct, marks, corrected, next_level_db, step_db, reversal, "
                "reversals, repeat, at_bound, speech_gain_db, noise_gain_db, limit_gain_db, response, answered_utc) "
                "VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    s.bind_row(trial.subject, trial.position, a.attempt, session, a.track, a.presentation, a.sentence_index,
               a.level_db, a.keywords, a.correct, a.auto_correct, a.marks, a.corrected, a.next_level_db, a.step_db,
               a.reversal, a.reversals, a.repeat, a.at_bound, a.speech_gain_db, a.noise_gain_db, a.limit_gain_db,
               a.response, answered_utc);
    s.run();
}

}  // namespace

void Store::commit_trial(int session, const PlannedTrial& trial, const Presentation& p, const Response& r) {
    Transaction tx(m_db);
    check_unanswered(m_db, trial);
    insert_trial(m_db, session, trial, p, r, utc_now());
    tx.commit();
}

void Store::commit_trial(int session, const PlannedTrial& trial, const Presentation& p, const Response& r,
                         const AdaptiveRecord& adaptive) {
    Transaction tx(m_db);
    check_unanswered(m_db, trial);
    const std::string now = utc_now();
    insert_trial(m_db, session, trial, p, r, now);
    insert_adaptive(m_db, session, trial, adaptive, now);
    tx.commit();
}

void Store::commit_attempt(int session, const PlannedTrial& trial, const AdaptiveRecord& adaptive) {
    Transaction tx(m_db);
    check_unanswered(m_db, trial);
    insert_adaptive(m_db, session, trial, adaptive, utc_now());
    tx.commit();
}

std::vector<Store::AdaptiveRow> Store::adaptive_trials(int subject) const {
    Statement s(m_db,
                "SELECT subject, position, session, attempt, track, presentation, sentence_index, level_db, keywords, "
                "correct, auto_correct, marks, corrected, next_level_db, step_db, reversal, reversals, repeat, "
                "at_bound, speech_gain_db, noise_gain_db, limit_gain_db, response, answered_utc FROM adaptive_trials "
                "WHERE ? = 0 OR subject = ? ORDER BY subject, position, attempt");
    s.bind(1, subject).bind(2, subject);
    std::vector<AdaptiveRow> out;
    while (s.step()) {
        Columns c(s);
        AdaptiveRow row;
        row.subject = c.integer();
        row.position = c.integer();
        row.session = c.integer();
        AdaptiveRecord& a = row.record;
        a.attempt = c.integer();
        a.track = c.text();
        a.presentation = c.integer();
        a.sentence_index = c.integer();
        a.level_db = c.real();
        a.keywords = c.integer();
        a.correct = c.integer();
        a.auto_correct = c.integer();
        a.marks = c.text();
        a.corrected = c.flag();
        a.next_level_db = c.real();
        a.step_db = c.real();
        a.reversal = c.flag();
        a.reversals = c.integer();
        a.repeat = c.flag();
        a.at_bound = c.flag();
        a.speech_gain_db = c.real();
        a.noise_gain_db = c.real();
        a.limit_gain_db = c.real();
        a.response = c.text();
        a.answered_utc = c.text();
        out.push_back(std::move(row));
    }
    return out;
}

OnlineImportCounts Store::import_online(const std::vector<OnlineSubject>& subjects, const std::string& event_detail) {
    OnlineImportCounts counts;
    Transaction tx(m_db);
    for (const OnlineSubject& subject : subjects) {
        const int id = subject.subject;
        // The plan: new subjects get it; a known subject must have the same.
        const std::vector<PlannedTrial> stored = planned_trials(id);
        if (stored.empty()) {
            Statement(m_db, "INSERT INTO subjects(subject, created_utc) VALUES(?, ?)").bind(1, id).bind(2, utc_now()).run();
            for (const auto& t : subject.plan) {
                Statement s(m_db,
                            "INSERT INTO planned_trials(subject, position, phase, block, list, condition, sentence, "
                            "stimulus) VALUES(?, ?, ?, ?, ?, ?, ?, ?)");
                s.bind_row(id, t.position, to_string(t.phase), t.block, t.list, t.condition, t.sentence, t.stimulus);
                s.run();
            }
            ++counts.subjects_added;
        } else if (stored != subject.plan) {
            throw InputError(m_path, fmt::format("subject {} is already stored with another trial list (a lab "
                                                 "session or an import from another export of the study); nothing "
                                                 "was imported",
                                                 id));
        }
        for (const OnlineSession& session : subject.sessions) {
            // One database session per browser session; a repeated import reuses it.
            int session_id = 0;
            {
                Statement find(m_db, "SELECT session, mode FROM sessions WHERE subject = ? AND external_id = ?");
                find.bind(1, id).bind(2, session.external_id);
                if (find.step()) session_id = find.integer(0);
            }
            if (session_id == 0) {
                Statement(m_db,
                          "INSERT INTO sessions(subject, started_utc, ended_utc, end_reason, first_position, details, "
                          "mode, external_id) VALUES(?, ?, ?, ?, ?, ?, 'online', ?)")
                    .bind_row(id, session.started_utc, session.ended_utc, session.end_reason, session.first_position,
                              session.details, session.external_id)
                    .run();
                session_id = static_cast<int>(sqlite3_last_insert_rowid(m_db));
                ++counts.sessions_added;
                Statement(m_db, "INSERT INTO events(session, subject, time_utc, kind, detail) VALUES(?, ?, ?, ?, ?)")
                    .bind_row(session_id, id, utc_now(), std::string("import-web"), event_detail)
                    .run();
                for (const auto& [kind, detail] : session.events)
                    Statement(m_db, "INSERT INTO events(session, subject, time_utc, kind, detail) VALUES(?, ?, ?, ?, ?)")
                        .bind_row(session_id, id, session.started_utc, kind, detail)
                        .run();
            } else {
                // A later import may know more of the session (it went on after the first export).
                Statement(m_db, "UPDATE sessions SET ended_utc = ?, end_reason = ?, details = ? WHERE session = ?")
                    .bind_row(session.ended_utc, session.end_reason, session.details, session_id)
                    .run();
            }
            for (const ScreeningTrial& t : session.screening_trials)
                Statement(m_db,
                          "INSERT OR REPLACE INTO screening_trials(subject, session, test, trial, answer, response, "
                          "correct, response_time_ms) VALUES(?, ?, ?, ?, ?, ?, ?, ?)")
                    .bind_row(id, session_id, t.test, t.trial, t.answer, t.response, t.correct, t.response_time_ms)
                    .run();
            for (const ScreeningResult& r : session.screening)
                Statement(m_db,
                          "INSERT OR REPLACE INTO screening(subject, session, test, trials, correct, required, passed) "
                          "VALUES(?, ?, ?, ?, ?, ?, ?)")
                    .bind_row(id, session_id, r.test, r.trials, r.correct, r.required, r.passed)
                    .run();
            for (const auto& t : session.trials) {
                Statement existing(m_db,
                                   "SELECT r.response, r.confirmed_empty, r.answered_utc, s.mode FROM responses r "
                                   "JOIN sessions s ON s.session = r.session WHERE r.subject = ? AND r.position = ?");
                existing.bind(1, id).bind(2, t.trial.position);
                if (existing.step()) {
                    // The same answer is the same text (and confirmation), whenever and wherever it was given.
                    const bool same = existing.text(0) == t.response.text &&
                                      (existing.integer(1) != 0) == t.response.confirmed_empty &&
                                      existing.text(3) == "online";
                    if (!same) {
                        const std::string message = fmt::format(
                            "subject {} trial {}: the answer \"{}\" differs from the one already in {} (\"{}\", {} "
                            "session, answered {}); nothing was imported",
                            id, t.trial.position, excerpt(t.response.text), m_path.string(), excerpt(existing.text(0)),
                            existing.text(3), existing.text(2));
                        if (t.source_file.empty()) throw InputError(m_path, message);
                        throw InputError(t.source_file, t.source_line, t.source_column, "response", message);
                    }
                    ++counts.trials_present;
                    continue;
                }
                insert_trial(m_db, session_id, t.trial, t.presentation, t.response, t.answered_utc);
                const WebPresentation& w = t.web;
                Statement(m_db,
                          "INSERT OR REPLACE INTO web_presentations(subject, position, frame_callbacks, presented_frames, "
                          "missed_callbacks, browser_dropped_frames, browser_total_frames, output_latency_ms, "
                          "base_latency_ms, audio_path_ms, audio_path_measured) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")
                    .bind_row(id, t.trial.position, w.frame_callbacks, w.presented_frames, w.missed_callbacks,
                              w.browser_dropped_frames, w.browser_total_frames, w.output_latency_ms,
                              w.base_latency_ms, w.audio_path_ms, w.audio_path_measured)
                    .run();
                ++counts.trials_added;
            }
        }
    }
    tx.commit();
    return counts;
}

std::vector<ResponseRow> Store::responses() const {
    Statement s(m_db,
                "SELECT p.subject, p.position, p.phase, p.block, p.list, p.condition, p.sentence, p.stimulus, "
                "r.session, r.response, r.response_time_ms, r.confirmed_empty, r.answered_utc, s.mode "
                "FROM responses r JOIN planned_trials p ON p.subject = r.subject AND p.position = r.position "
                "JOIN sessions s ON s.session = r.session ORDER BY p.subject, p.position");
    std::vector<ResponseRow> out;
    while (s.step()) {
        Columns c(s);
        ResponseRow row;
        row.trial.subject = c.integer();
        row.trial.position = c.integer();
        parse_phase(c.text(), row.trial.phase);
        row.trial.block = c.integer();
        row.trial.list = c.text();
        row.trial.condition = c.text();
        row.trial.sentence = c.text();
        row.trial.stimulus = c.text();
        row.session = c.integer();
        row.response.text = c.text();
        row.response.response_time_ms = c.real();
        row.response.confirmed_empty = c.flag();
        row.answered_utc = c.text();
        row.mode = c.text();
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
        Columns c(s);
        TimingRow row;
        row.subject = c.integer();
        row.position = c.integer();
        row.session = c.integer();
        Presentation& p = row.presentation;
        p.audio_onset_s = c.real();
        p.video_onset_s = c.real();
        p.duration_s = c.real();
        p.refresh_hz = c.real();
        p.frames_total = c.integer();
        p.frames_shown = c.integer();
        p.dropped_frames = c.integer();
        p.repeated_frames = c.integer();
        p.mean_offset_ms = c.real();
        p.max_abs_offset_ms = c.real();
        if (with_frames) {
            Statement f(m_db, "SELECT frame, pts_s, flip_s, offset_ms FROM frames WHERE subject = ? AND "
                              "position = ? ORDER BY frame");
            f.bind_row(row.subject, row.position);
            while (f.step()) {
                Columns fc(f);
                p.flips.push_back({fc.integer(), fc.real(), fc.real(), fc.real()});
            }
        }
        out.push_back(std::move(row));
    }
    return out;
}

std::vector<Store::WebTimingRow> Store::web_timing() const {
    Statement s(m_db,
                "SELECT subject, position, frame_callbacks, presented_frames, missed_callbacks, browser_dropped_frames, "
                "browser_total_frames, output_latency_ms, base_latency_ms, audio_path_ms, audio_path_measured FROM web_presentations "
                "ORDER BY subject, position");
    std::vector<WebTimingRow> out;
    while (s.step()) {
        Columns c(s);
        WebTimingRow row;
        row.subject = c.integer();
        row.position = c.integer();
        row.web.frame_callbacks = c.flag();
        row.web.presented_frames = c.integer();
        row.web.missed_callbacks = c.integer();
        row.web.browser_dropped_frames = c.integer();
        row.web.browser_total_frames = c.integer();
        row.web.output_latency_ms = c.real();
        row.web.base_latency_ms = c.real();
        row.web.audio_path_ms = c.real();
        row.web.audio_path_measured = c.flag();
        out.push_back(row);
    }
    return out;
}

std::vector<Store::ScreeningRow> Store::screening() const {
    Statement s(m_db, "SELECT subject, session, test, trials, correct, required, passed FROM screening "
                      "ORDER BY subject, session, test");
    std::vector<ScreeningRow> out;
    while (s.step()) {
        Columns c(s);
        out.push_back({c.integer(), c.integer(), {c.text(), c.integer(), c.integer(), c.integer(), c.flag()}});
    }
    return out;
}

std::vector<Store::ScreeningTrialRow> Store::screening_trials() const {
    Statement s(m_db, "SELECT subject, session, test, trial, answer, response, correct, response_time_ms "
                      "FROM screening_trials ORDER BY subject, session, test, trial");
    std::vector<ScreeningTrialRow> out;
    while (s.step()) {
        Columns c(s);
        out.push_back({c.integer(), c.integer(), {c.text(), c.integer(), c.integer(), c.integer(), c.flag(), c.real()}});
    }
    return out;
}

std::vector<Store::EventRow> Store::events() const {
    Statement s(m_db, "SELECT session, subject, time_utc, kind, detail FROM events ORDER BY id");
    std::vector<EventRow> out;
    while (s.step()) {
        Columns c(s);
        out.push_back({c.integer(), c.integer(), c.text(), c.text(), c.text()});
    }
    return out;
}

std::vector<int> Store::subjects() const {
    Statement s(m_db, "SELECT subject FROM subjects ORDER BY subject");
    std::vector<int> out;
    while (s.step()) out.push_back(s.integer(0));
    return out;
}

namespace {

std::string csv_number(double v) { return fmt::format("{:.6f}", v); }
std::string csv_ms(double v) { return fmt::format("{:.3f}", v); }

// responses.csv: the analysis input columns first, then extras.
std::string responses_csv(const Store& store) {
    std::string csv = csv_line({"subject", "session", "trial", "phase", "condition", "list", "sentence",
                                "response", "response_time_ms", "block", "stimulus", "confirmed_empty",
                                "answered_utc", "mode"});
    for (const auto& r : store.responses())
        csv += csv_line({std::to_string(r.trial.subject), std::to_string(r.session),
                         std::to_string(r.trial.position), to_string(r.trial.phase), r.trial.condition,
                         r.trial.list, r.trial.sentence, r.response.text, csv_ms(r.response.response_time_ms),
                         std::to_string(r.trial.block), r.trial.stimulus,
                         r.response.confirmed_empty ? "1" : "0", r.answered_utc, r.mode});
    return csv;
}

// timing.csv (one row per presentation) and frames.csv (one per frame).
std::pair<std::string, std::string> timing_and_frames_csv(const std::vector<Store::TimingRow>& timing) {
    const auto num = csv_number;
    const auto ms = csv_ms;
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
    return {timing_csv, frames_csv};
}

// timing_summary.csv: one row per session, what a methods section reports.
std::string timing_summary_csv(const std::vector<Store::TimingRow>& timing) {
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
                                 csv_ms(s.offsets ? s.sum_offset_ms / s.offsets : 0.0), csv_ms(s.max_abs_offset_ms)});
    return summary_csv;
}

// sessions.csv: every session of every subject.
std::string sessions_csv(const Store& store) {
    std::string csv =
        csv_line({"subject", "session", "started_utc", "ended_utc", "end_reason", "first_trial", "mode", "details"});
    for (int subject : store.subjects())
        for (const auto& s : store.sessions(subject))
            csv += csv_line({std::to_string(s.subject), std::to_string(s.session), s.started_utc,
                             s.ended_utc, s.end_reason.empty() ? "open" : s.end_reason,
                             std::to_string(s.first_position), s.mode, s.details});
    return csv;
}

// events.csv: the session log.
std::string events_csv(const Store& store) {
    std::string csv = csv_line({"session", "subject", "time_utc", "kind", "detail"});
    for (const auto& e : store.events())
        csv += csv_line({std::to_string(e.session), std::to_string(e.subject), e.time_utc, e.kind, e.detail});
    return csv;
}

// adaptive_trials.csv: every presentation of an adaptive track with its level and score.
std::string adaptive_trials_csv(const Store& store, const std::vector<Store::AdaptiveRow>& adaptive) {
    std::map<std::pair<int, int>, PlannedTrial> planned;
    for (int subject : store.subjects())
        for (auto& t : store.planned_trials(subject)) planned[{subject, t.position}] = t;
    // Levels in full precision: the analysis replays the tracks and compares.
    auto full = [](double v) { return fmt::format("{}", v); };
    std::string csv = csv_line({"subject", "session", "trial", "attempt", "phase", "condition", "track",
                                "presentation", "sentence_index", "sentence", "level_db", "keywords", "correct",
                                "auto_correct", "marks", "corrected", "next_level_db", "step_db", "reversal",
                                "reversals", "repeat", "at_bound", "speech_gain_db", "noise_gain_db",
                                "limit_gain_db", "response", "answered_utc"});
    for (const auto& row : adaptive) {
        const auto it = planned.find({row.subject, row.position});
        const PlannedTrial t = it == planned.end() ? PlannedTrial{} : it->second;
        const AdaptiveRecord& a = row.record;
        csv += csv_line({std::to_string(row.subject), std::to_string(row.session), std::to_string(row.position),
                         std::to_string(a.attempt), to_string(t.phase), t.condition, a.track,
                         std::to_string(a.presentation), std::to_string(a.sentence_index), t.sentence,
                         full(a.level_db), std::to_string(a.keywords), std::to_string(a.correct),
                         std::to_string(a.auto_correct), a.marks, a.corrected ? "1" : "0", full(a.next_level_db),
                         full(a.step_db), a.reversal ? "1" : "0", std::to_string(a.reversals),
                         a.repeat ? "1" : "0", a.at_bound ? "1" : "0", full(a.speech_gain_db),
                         full(a.noise_gain_db), full(a.limit_gain_db), a.response, a.answered_utc});
    }
    return csv;
}

// web_timing.csv: the browser's timing of each online presentation.
std::string web_timing_csv(const std::vector<Store::WebTimingRow>& web) {
    const auto ms = csv_ms;
    std::string csv = csv_line({"subject", "trial", "frame_callbacks", "presented_frames", "missed_callbacks",
                                "browser_dropped_frames", "browser_total_frames", "output_latency_ms",
                                "base_latency_ms", "audio_path_ms", "audio_path_measured"});
    for (const auto& w : web)
        csv += csv_line({std::to_string(w.subject), std::to_string(w.position), w.web.frame_callbacks ? "1" : "0",
                         std::to_string(w.web.presented_frames), std::to_string(w.web.missed_callbacks),
                         std::to_string(w.web.browser_dropped_frames), std::to_string(w.web.browser_total_frames),
                         ms(w.web.output_latency_ms), ms(w.web.base_latency_ms), ms(w.web.audio_path_ms),
                         w.web.audio_path_measured ? "1" : "0"});
    return csv;
}

// screening.csv: the outcome of each headphone check.
std::string screening_csv(const std::vector<Store::ScreeningRow>& screening) {
    std::string csv = csv_line({"subject", "session", "test", "trials", "correct", "required", "passed"});
    for (const auto& r : screening)
        csv += csv_line({std::to_string(r.subject), std::to_string(r.session), r.result.test,
                         std::to_string(r.result.trials), std::to_string(r.result.correct),
                         std::to_string(r.result.required), r.result.passed ? "1" : "0"});
    return csv;
}

// screening_trials.csv: each trial of the headphone checks.
std::string screening_trials_csv(const std::vector<Store::ScreeningTrialRow>& screening_trials) {
    std::string csv = csv_line({"subject", "session", "test", "trial", "answer", "response", "correct",
                                "response_time_ms"});
    for (const auto& t : screening_trials)
        csv += csv_line({std::to_string(t.subject), std::to_string(t.session), t.trial.test,
                         std::to_string(t.trial.trial), std::to_string(t.trial.answer),
                         std::to_string(t.trial.response), t.trial.correct ? "1" : "0",
                         csv_ms(t.trial.response_time_ms)});
    return csv;
}

}  // namespace

std::vector<std::filesystem::path> export_store(const Store& store, const std::filesystem::path& out_dir) {
    std::vector<std::filesystem::path> written;
    auto write = [&](const char* name, const std::string& text) {
        written.push_back(out_dir / name);
        write_text_file(written.back(), text);
    };
    write("responses.csv", responses_csv(store));
    const auto timing = store.timing(true);
    const auto [timing_csv, frames_csv] = timing_and_frames_csv(timing);
    write("timing_summary.csv", timing_summary_csv(timing));
    write("timing.csv", timing_csv);
    write("frames.csv", frames_csv);
    write("sessions.csv", sessions_csv(store));
    write("events.csv", events_csv(store));
    if (const auto adaptive = store.adaptive_trials(); !adaptive.empty())
        write("adaptive_trials.csv", adaptive_trials_csv(store, adaptive));
    // Online sessions: browser timing and headphone checks.
    const auto web = store.web_timing();
    const auto screening = store.screening();
    const auto screening_trials = store.screening_trials();
    if (!web.empty() || !screening.empty() || !screening_trials.empty()) {
        write("web_timing.csv", web_timing_csv(web));
        // Per participant: the timing certificate (timing_certificate.h) with the default tolerances.
        const TimingTolerance tolerance;
        write("timing_certificate.csv", timing_certificate_csv(timing_certificates(store, tolerance), tolerance));
        write("screening.csv", screening_csv(screening));
        write("screening_trials.csv", screening_trials_csv(screening_trials));
    }
    return written;
}

}  // namespace avsi::experiment
