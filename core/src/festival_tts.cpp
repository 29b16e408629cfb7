// Festival through its C++ library (libFestival + Edinburgh Speech Tools),
// run in a helper process so that its global state never touches the caller.
//
// Festival is one global Scheme (SIOD) interpreter: its garbage collector
// scans the C stack between the interpreter's recorded stack start and the
// current frame, its errors longjmp out of C++ frames or call exit(), and
// voices change global parameters. So the calling process never runs it:
//
//   caller ──(SOCK_SEQPACKET: request + a pipe's write end, SCM_RIGHTS)──► server
//   server: forked once, single-threaded, festival_initialize() done, waits
//   server ──fork per request──► worker: selects the voice, synthesises,
//             writes the answer into the caller's pipe, _exit()s
//
// Every utterance starts from the same freshly initialised interpreter (the
// server's state, copied by fork), so the output never depends on what was
// spoken before or in which order; workers run in parallel; a Festival crash
// or exit() ends one worker, whose caller gets an error. See docs/tts.md.
//
// This file includes festival.h, which puts `using namespace std` in every
// file that includes it: it is kept out of the unity build (core/CMakeLists.txt).
#include "festival_tts.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "wire.h"

#include <festival/festival.h>

namespace avsi::detail {

namespace {

// Festival's heap in cells (~24 bytes each; festival's own default is 10
// million, which the server would touch in full at start-up: 330 MB). Two
// million cells hold an utterance of a few minutes.
constexpr int k_heap_cells = 2'000'000;
// Longest text one request carries (it travels in one socket message).
constexpr std::size_t k_max_text_bytes = 64 * 1024;

enum RequestKind : std::int64_t { Synthesize = 1, ListVoices = 2, VoiceInfo = 3 };
enum Status : std::int64_t { Ok = 0, BadInput = 1, Failure = 2 };

struct Request {
    std::int64_t kind = 0;
    std::string voice;
    std::string text;
};

// --- Festival calls (in a worker only) --------------------------------------

// Festival's messages (stdout and stderr) go to this memory file, so a failure
// can quote them and nothing reaches the caller's terminal.
int g_log_fd = -1;

std::string festival_log() {
    if (g_log_fd < 0) return {};
    std::fflush(stdout);
    std::fflush(stderr);
    const off_t size = ::lseek(g_log_fd, 0, SEEK_END);
    if (size <= 0) return {};
    const std::size_t keep = std::min<std::size_t>(static_cast<std::size_t>(size), 2000);
    std::string text(keep, '\0');
    if (::pread(g_log_fd, text.data(), keep, size - static_cast<off_t>(keep)) != static_cast<ssize_t>(keep)) return {};
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
}

// Evaluates a Scheme expression; on a Scheme error throws with Festival's message.
void eval(const std::string& expression) {
    if (!festival_eval_command(EST_String(expression.c_str()))) {
        const std::string log = festival_log();
        throw std::runtime_error(fmt::format("Festival failed evaluating {}{}", expression,
                                             log.empty() ? "" : ": " + log));
    }
}

std::string lisp_string(const char* variable) {
    const LISP value = siod_get_lval(variable, nullptr);
    return value == NIL ? std::string() : std::string(get_c_string(value));
}

std::vector<std::string> voice_list() {
    eval("(set! avsi_voices (voice.list))");
    std::vector<std::string> names;
    for (LISP l = siod_get_lval("avsi_voices", nullptr); l != NIL; l = cdr(l)) names.emplace_back(get_c_string(car(l)));
    std::sort(names.begin(), names.end());
    names.erase(std::unique(names.begin(), names.end()), names.end());
    return names;
}

// Throws InputError "voice" unless `voice` is installed; returns nothing.
void check_voice(const std::string& voice) {
    const auto installed = voice_list();
    if (std::find(installed.begin(), installed.end(), voice) != installed.end()) return;
    std::string list;
    for (const auto& v : installed) list += (list.empty() ? "" : ", ") + v;
    const std::string close = closest_match(voice, installed);
    throw InputError("tts", 0, 0, "voice",
                     fmt::format("unknown Festival voice \"{}\"{}; installed Festival voices: {}", voice,
                                 close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close),
                                 list.empty() ? "none (install festvox-us-slt-hts)" : list));
}

void answer_synthesize(const Request& r, WireWriter& w) {
    check_voice(r.voice);  // the name is then one of voice.list's symbols, safe to splice
    eval(fmt::format("(voice_{})", r.voice));
    eval("(set! avsi_phone_set (Parameter.get 'PhoneSet))");
    const std::string phone_set = lisp_string("avsi_phone_set");
    siod_set_lval("avsi_text", strintern(r.text.c_str()));
    eval("(set! avsi_utt (SynthText avsi_text))");
    const LISP utt_value = siod_get_lval("avsi_utt", nullptr);
    if (utt_value == NIL || !utterance_p(utt_value)) throw std::runtime_error("Festival returned no utterance");
    EST_Utterance* utt = utterance(utt_value);
    if (!utt->relation_present("Segment") || !utt->relation_present("Wave") || !utt->relation("Wave")->head())
        throw std::runtime_error(fmt::format("Festival voice {} made no Segment or Wave relation", r.voice));
    EST_Item* wave_item = utt->relation("Wave")->head();
    const EST_Wave* wave = ::wave(wave_item->f("wave"));
    if (!wave || wave->num_channels() != 1 || wave->sample_rate() <= 0)
        throw std::runtime_error(fmt::format("Festival voice {} made no mono waveform", r.voice));

    std::vector<FestivalSegment> segments;
    for (EST_Item* s = utt->relation("Segment")->head(); s; s = inext(s)) {
        FestivalSegment seg;
        seg.name = static_cast<const char*>(s->name());
        seg.end_s = ffeature(s, "end").Float();
        seg.stressed = ffeature(s, "R:SylStructure.parent.stress").Int() > 0;
        segments.push_back(std::move(seg));
    }
    w.i64(Ok);
    w.str(phone_set);
    w.i64(wave->sample_rate());
    w.i64(static_cast<std::int64_t>(segments.size()));
    for (const auto& s : segments) {
        w.str(s.name);
        w.f64(s.end_s);
        w.i64(s.stressed ? 1 : 0);
    }
    const int n = wave->num_samples();
    std::vector<std::int16_t> samples(static_cast<std::size_t>(std::max(n, 0)));
    for (int i = 0; i < n; ++i) samples[static_cast<std::size_t>(i)] = wave->a_no_check(i, 0);
    w.i64(n);
    w.bytes(samples.data(), samples.size() * sizeof(std::int16_t));
}

void answer_voice_info(const Request& r, WireWriter& w) {
    check_voice(r.voice);
    eval(fmt::format("(set! avsi_voice_dir (cdr (assoc '{} voice-locations)))", r.voice));
    w.i64(Ok);
    w.str(festival_version);
    w.str(r.voice);
    w.str(lisp_string("avsi_voice_dir"));
}

// The worker: answers one request into `out_fd` and exits.
[[noreturn]] void run_worker(const Request& r, int out_fd) {
    ::signal(SIGCHLD, SIG_DFL);
    g_log_fd = ::memfd_create("avsi-festival-log", 0);
    if (g_log_fd >= 0) {
        ::dup2(g_log_fd, STDOUT_FILENO);
        ::dup2(g_log_fd, STDERR_FILENO);
    }
    WireWriter w;
    try {
        if (r.kind == Synthesize) {
            answer_synthesize(r, w);
        } else if (r.kind == ListVoices) {
            const auto voices = voice_list();
            w.i64(Ok);
            w.i64(static_cast<std::int64_t>(voices.size()));
            for (const auto& v : voices) w.str(v);
        } else if (r.kind == VoiceInfo) {
            answer_voice_info(r, w);
        } else {
            throw std::runtime_error("unknown request");
        }
    } catch (const InputError& e) {
        w.clear();
        w.i64(BadInput);
        w.str(e.first().field);
        w.str(e.first().message);
    } catch (const std::exception& e) {
        w.clear();
        w.i64(Failure);
        w.str(e.what());
    }
    const std::string& message = w.data();
    std::size_t done = 0;
    while (done < message.size()) {
        const ssize_t n = ::write(out_fd, message.data() + done, message.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) ::_exit(3);
        done += static_cast<std::size_t>(n);
    }
    ::_exit(0);  // none of the server's state is torn down
}

// --- The server process -----------------------------------------------------

constexpr int k_server_fd = 3;  // the server's end of the socket, moved here

// Receives one request and the descriptor sent with it; false when the caller
// has gone (end of file) or the message is unusable.
bool receive_request(Request& r, int& fd, bool& closed) {
    static std::vector<char> buffer(k_max_text_bytes + 4096);
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))];
    iovec iov{buffer.data(), buffer.size()};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    ssize_t n;
    do n = ::recvmsg(k_server_fd, &msg, 0);
    while (n < 0 && errno == EINTR);
    fd = -1;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c))
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_RIGHTS) std::memcpy(&fd, CMSG_DATA(c), sizeof(int));
    closed = n <= 0;
    if (closed || (msg.msg_flags & (MSG_TRUNC | MSG_CTRUNC)) || fd < 0) return false;
    try {
        const std::string bytes(buffer.data(), static_cast<std::size_t>(n));
        WireReader reader(bytes, "festival request");
        r.kind = reader.i64();
        r.voice = reader.str();
        r.text = reader.str();
    } catch (const std::exception&) {
        return false;
    }
    return true;
}

[[noreturn]] void run_server(int socket_fd) {
    // Only the socket stays open (as fd 3), with stdin/stdout/stderr on
    // /dev/null: the server must hold none of the caller's descriptors
    // (a pipe's write end kept open here would never let its reader finish).
    if (socket_fd != k_server_fd) {
        ::dup2(socket_fd, k_server_fd);
        ::close(socket_fd);
    }
    const int null_fd = ::open("/dev/null", O_RDWR);
    if (null_fd >= 0) {
        for (int fd = 0; fd <= 2; ++fd) ::dup2(null_fd, fd);
        if (null_fd > 2 && null_fd != k_server_fd) ::close(null_fd);
    }
    if (::close_range(k_server_fd + 1, ~0U, 0) != 0) {  // kernels before 5.9
        const long limit = std::min(::sysconf(_SC_OPEN_MAX), 65536L);
        for (int fd = k_server_fd + 1; fd < limit; ++fd) ::close(fd);
    }
    sigset_t all;
    sigemptyset(&all);
    ::sigprocmask(SIG_SETMASK, &all, nullptr);
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) ::signal(sig, SIG_DFL);
    ::signal(SIGPIPE, SIG_IGN);
    ::signal(SIGCHLD, SIG_IGN);  // workers are reaped by the kernel

    // Festival's init.scm loads $HOME/.festivalrc: a user's own settings would
    // make the speech depend on who builds it. The server has no HOME.
    ::setenv("HOME", "/nonexistent", 1);
    festival_initialize(1, k_heap_cells);
    const char ready = 1;
    if (::send(k_server_fd, &ready, 1, MSG_NOSIGNAL) != 1) ::_exit(0);

    for (;;) {
        Request r;
        int fd = -1;
        bool closed = false;
        const bool ok = receive_request(r, fd, closed);
        if (closed) ::_exit(0);  // the caller has exited
        if (!ok) {
            if (fd >= 0) ::close(fd);
            continue;
        }
        const pid_t pid = ::fork();
        if (pid == 0) {
            ::close(k_server_fd);
            run_worker(r, fd);
        }
        ::close(fd);  // the worker has it (or the fork failed: the caller reads end of file)
    }
}

// --- The caller's side ------------------------------------------------------

class FestivalServer {
public:
    static FestivalServer& instance() {
        static FestivalServer server;
        return server;
    }

    // Sends a request and returns the worker's answer (the whole message).
    std::string call(const Request& r) {
        WireWriter w;
        w.i64(r.kind);
        w.str(r.voice);
        w.str(r.text);
        int fds[2];
        if (::pipe2(fds, O_CLOEXEC) != 0)
            throw std::runtime_error(fmt::format("festival: pipe failed: {}", std::strerror(errno)));
        try {
            std::lock_guard lock(m_mutex);
            for (int attempt = 0;; ++attempt) {
                if (m_socket < 0) start();
                if (send_with_fd(w.data(), fds[1])) break;
                stop();  // the server died; start a new one once
                if (attempt == 1)
                    throw std::runtime_error(fmt::format("festival: the server process is not answering: {}",
                                                         std::strerror(errno)));
            }
        } catch (...) {
            ::close(fds[0]);
            ::close(fds[1]);
            throw;
        }
        ::close(fds[1]);
        std::string answer;
        char buffer[1 << 16];
        for (;;) {
            const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) break;
            answer.append(buffer, static_cast<std::size_t>(n));
        }
        ::close(fds[0]);
        if (answer.empty())
            throw std::runtime_error("festival: the worker process ended without an answer (Festival crashed)");
        return answer;
    }

private:
    FestivalServer() = default;
    ~FestivalServer() { stop(); }

    void start() {
        int sv[2];
        if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0)
            throw std::runtime_error(fmt::format("festival: socketpair failed: {}", std::strerror(errno)));
        const pid_t pid = ::fork();
        if (pid < 0) {
            ::close(sv[0]);
            ::close(sv[1]);
            throw std::runtime_error(fmt::format("festival: fork failed: {}", std::strerror(errno)));
        }
        if (pid == 0) {
            ::close(sv[0]);
            run_server(sv[1]);
        }
        ::close(sv[1]);
        m_socket = sv[0];
        m_pid = pid;
        // Wait for festival_initialize (a fraction of a second; a minute is a hang).
        pollfd p{m_socket, POLLIN, 0};
        char ready = 0;
        int polled;
        do polled = ::poll(&p, 1, 60'000);
        while (polled < 0 && errno == EINTR);
        if (polled <= 0 || ::recv(m_socket, &ready, 1, 0) != 1 || ready != 1) {
            stop();
            throw std::runtime_error(
                "festival: Festival could not be initialised (are the festival and festvox-us-slt-hts "
                "packages installed? scripts/install-deps installs them)");
        }
    }

    void stop() {
        if (m_socket >= 0) ::close(m_socket);
        m_socket = -1;
        if (m_pid > 0) {
            // Closing the socket ends the server; reap it (it may be in
            // festival_initialize still, so do not wait for ever).
            for (int i = 0; i < 200; ++i) {
                const pid_t done = ::waitpid(m_pid, nullptr, WNOHANG);
                if (done == m_pid || (done < 0 && errno != EINTR)) break;
                if (i == 199) {
                    ::kill(m_pid, SIGKILL);
                    ::waitpid(m_pid, nullptr, 0);
                    break;
                }
                ::usleep(5'000);
            }
        }
        m_pid = -1;
    }

    bool send_with_fd(const std::string& message, int fd) {
        alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
        iovec iov{const_cast<char*>(message.data()), message.size()};
        msghdr msg{};
        msg.msg_iov = &iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control;
        msg.msg_controllen = sizeof control;
        cmsghdr* c = CMSG_FIRSTHDR(&msg);
        c->cmsg_level = SOL_SOCKET;
        c->cmsg_type = SCM_RIGHTS;
        c->cmsg_len = CMSG_LEN(sizeof(int));
        std::memcpy(CMSG_DATA(c), &fd, sizeof(int));
        ssize_t n;
        do n = ::sendmsg(m_socket, &msg, MSG_NOSIGNAL);
        while (n < 0 && errno == EINTR);
        return n == static_cast<ssize_t>(message.size());
    }

    std::mutex m_mutex;
    int m_socket = -1;
    pid_t m_pid = -1;
};

// Sends `r`; returns a reader positioned after an Ok status, or throws the
// worker's InputError / failure.
std::string call_ok(const Request& r) {
    std::string answer = FestivalServer::instance().call(r);
    WireReader reader(answer, "festival answer");
    const std::int64_t status = reader.i64();
    if (status == BadInput) {
        std::string field = reader.str();
        std::string message = reader.str();
        throw InputError("tts", 0, 0, std::move(field), std::move(message));
    }
    if (status != Ok) throw std::runtime_error(reader.str());
    return answer.substr(sizeof(std::int64_t));
}

}  // namespace

FestivalUtterance festival_synthesize(const std::string& text, const std::string& voice) {
    if (text.size() > k_max_text_bytes)
        throw InputError("tts", 0, 0, "text",
                         fmt::format("expected at most {} bytes of text for Festival, got {}", k_max_text_bytes,
                                     text.size()));
    const std::string answer = call_ok({Synthesize, voice, text});
    WireReader reader(answer, "festival answer");
    FestivalUtterance u;
    u.phone_set = reader.str();
    u.sample_rate_hz = static_cast<int>(reader.i64());
    u.segments.resize(reader.count(3 * sizeof(std::int64_t)));
    for (auto& s : u.segments) {
        s.name = reader.str();
        s.end_s = reader.f64();
        s.stressed = reader.i64() != 0;
    }
    u.samples.resize(reader.count(sizeof(std::int16_t)));
    reader.bytes(u.samples.data(), u.samples.size() * sizeof(std::int16_t));
    return u;
}

std::vector<std::string> festival_voices() {
    const std::string answer = call_ok({ListVoices, "", ""});
    WireReader reader(answer, "festival answer");
    std::vector<std::string> voices(reader.count(sizeof(std::int64_t)));
    for (auto& v : voices) v = reader.str();
    return voices;
}

FestivalVoiceInfo festival_voice_info(const std::string& voice) {
    const std::string answer = call_ok({VoiceInfo, voice, ""});
    WireReader reader(answer, "festival answer");
    FestivalVoiceInfo info;
    info.festival_version = reader.str();
    info.voice = reader.str();
    info.directory = reader.str();
    return info;
}

}  // namespace avsi::detail
