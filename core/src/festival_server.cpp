// avsi-festival: Festival (libFestival + the Edinburgh Speech Tools) in a
// process of its own, started by the first Festival call of an avsi process
// (festival_tts.cpp) with its socket as descriptor 3.
//
// Festival is one global Scheme (SIOD) interpreter: its garbage collector
// scans the C stack between the interpreter's recorded stack start and the
// current frame, its errors longjmp out of C++ frames or call exit(), and
// voices change global parameters. So no avsi process runs it, and none loads
// its libraries (about 4 ms of every start-up):
//
//   caller ──(SOCK_SEQPACKET: request + a pipe's write end, SCM_RIGHTS)──► server
//   server: this executable, single-threaded, festival_initialize() done, waits
//   server ──fork per request──► worker: selects the voice, synthesises,
//             writes the answer into the caller's pipe, _exit()s
//
// Every utterance starts from the same freshly initialised interpreter (the
// server's state, copied by fork), so the output never depends on what was
// spoken before or in which order; workers run in parallel; a Festival crash
// or exit() ends one worker, whose caller gets an error. See docs/tts.md.
//
// festival.h puts `using namespace std` in every file that includes it; this
// is the only one.
#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "festival_protocol.h"
#include "wire.h"

#include <festival/festival.h>

namespace avsi::detail {

namespace {

namespace proto = festival_protocol;

// Festival's heap in cells (~24 bytes each; festival's own default is 10
// million, which the server would touch in full at start-up: 330 MB). Two
// million cells hold an utterance of a few minutes.
constexpr int k_heap_cells = 2'000'000;

struct Request {
    std::int64_t kind = 0;
    std::string voice;
    std::string text;
};

// A voice that is not installed: answered with the installed ones.
struct UnknownVoiceError {
    std::vector<std::string> installed;
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

// Throws UnknownVoiceError unless `voice` is installed.
void check_voice(const std::string& voice) {
    auto installed = voice_list();
    if (std::find(installed.begin(), installed.end(), voice) == installed.end())
        throw UnknownVoiceError{std::move(installed)};
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

    w.i64(proto::Ok);
    w.str(phone_set);
    w.i64(wave->sample_rate());
    std::int64_t count = 0;
    for (EST_Item* s = utt->relation("Segment")->head(); s; s = inext(s)) ++count;
    w.i64(count);
    for (EST_Item* s = utt->relation("Segment")->head(); s; s = inext(s)) {
        w.str(static_cast<const char*>(s->name()));
        w.f64(ffeature(s, "end").Float());
        w.i64(ffeature(s, "R:SylStructure.parent.stress").Int() > 0 ? 1 : 0);
    }
    const int n = wave->num_samples();
    std::vector<std::int16_t> samples(static_cast<std::size_t>(std::max(n, 0)));
    for (int i = 0; i < n; ++i) samples[static_cast<std::size_t>(i)] = wave->a_no_check(i, 0);
    w.i64(static_cast<std::int64_t>(samples.size()));
    w.bytes(samples.data(), samples.size() * sizeof(std::int16_t));
}

void answer_voice_info(const Request& r, WireWriter& w) {
    check_voice(r.voice);
    eval(fmt::format("(set! avsi_voice_dir (cdr (assoc '{} voice-locations)))", r.voice));
    w.i64(proto::Ok);
    w.str(festival_version);
    w.str(r.voice);
    w.str(lisp_string("avsi_voice_dir"));
}

// The dictionary entry of each word (lines of r.text) under the voice's
// lexicon: whether the lexicon or its addenda hold it (lex.lookup_all, which
// ignores letter-to-sound) and its phones with syllable stress (lex.lookup,
// which falls back on the voice's letter-to-sound rules). No post-lexical rules.
void answer_transcribe(const Request& r, WireWriter& w) {
    check_voice(r.voice);
    eval(fmt::format("(voice_{})", r.voice));
    eval("(set! avsi_phone_set (Parameter.get 'PhoneSet))");
    std::vector<std::string> words;
    std::size_t from = 0;
    while (from <= r.text.size()) {
        const std::size_t end = std::min(r.text.find('\n', from), r.text.size());
        if (end > from) words.push_back(r.text.substr(from, end - from));
        from = end + 1;
    }
    w.i64(proto::Ok);
    w.str(lisp_string("avsi_phone_set"));
    w.i64(static_cast<std::int64_t>(words.size()));
    for (const auto& word : words) {
        siod_set_lval("avsi_word", strcons(static_cast<long>(word.size()), word.c_str()));
        eval("(set! avsi_known (lex.lookup_all avsi_word))");
        eval("(set! avsi_entry (lex.lookup avsi_word nil))");
        w.i64(siod_get_lval("avsi_known", nullptr) == NIL ? 0 : 1);
        std::vector<std::pair<std::string, bool>> phones;
        const LISP entry = siod_get_lval("avsi_entry", nullptr);
        const LISP syllables = siod_llength(entry) >= 3 ? car(cdr(cdr(entry))) : NIL;
        for (LISP syl = syllables; syl != NIL; syl = cdr(syl)) {
            const bool stressed = siod_llength(car(syl)) >= 2 && get_c_int(car(cdr(car(syl)))) > 0;
            for (LISP p = car(car(syl)); p != NIL; p = cdr(p)) phones.emplace_back(get_c_string(car(p)), stressed);
        }
        w.i64(static_cast<std::int64_t>(phones.size()));
        for (const auto& [name, stressed] : phones) {
            w.str(name);
            w.i64(stressed ? 1 : 0);
        }
    }
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
        if (r.kind == proto::Synthesize) {
            answer_synthesize(r, w);
        } else if (r.kind == proto::ListVoices) {
            const auto voices = voice_list();
            w.i64(proto::Ok);
            w.i64(static_cast<std::int64_t>(voices.size()));
            for (const auto& v : voices) w.str(v);
        } else if (r.kind == proto::VoiceInfo) {
            answer_voice_info(r, w);
        } else if (r.kind == proto::Transcribe) {
            answer_transcribe(r, w);
        } else {
            throw std::runtime_error("unknown request");
        }
    } catch (const UnknownVoiceError& e) {
        w.clear();
        w.i64(proto::UnknownVoice);
        w.i64(static_cast<std::int64_t>(e.installed.size()));
        for (const auto& v : e.installed) w.str(v);
    } catch (const std::exception& e) {
        w.clear();
        w.i64(proto::Failure);
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

// --- The server -------------------------------------------------------------

// Receives one request and the descriptor sent with it; false when the caller
// has gone (end of file) or the message is unusable.
bool receive_request(Request& r, int& fd, bool& closed) {
    static std::vector<char> buffer(proto::k_max_text_bytes + 4096);
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))];
    iovec iov{buffer.data(), buffer.size()};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    ssize_t n;
    do n = ::recvmsg(proto::k_server_fd, &msg, MSG_CMSG_CLOEXEC);
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

[[noreturn]] void run_server() {
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
    if (::send(proto::k_server_fd, &proto::k_ready, 1, MSG_NOSIGNAL) != 1) ::_exit(0);

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
            ::close(proto::k_server_fd);
            run_worker(r, fd);
        }
        ::close(fd);  // the worker has it (or the fork failed: the caller reads end of file)
    }
}

}  // namespace

}  // namespace avsi::detail

int main(int argc, char** argv) {
    // Started by avsi with its socket as descriptor 3 (a SOCK_SEQPACKET
    // socket): anything else is a person trying it by hand.
    int type = 0;
    socklen_t length = sizeof type;
    if (argc != 1 || ::getsockopt(avsi::detail::festival_protocol::k_server_fd, SOL_SOCKET, SO_TYPE, &type, &length) != 0 ||
        type != SOCK_SEQPACKET) {
        std::fprintf(stderr,
                     "%s: the Festival server of avsi; avsi starts it when a Festival voice is asked for "
                     "(e.g. avsi phones --tts festival:cmu_us_slt_arctic_hts). It takes no arguments.\n",
                     argc > 0 ? argv[0] : "avsi-festival");
        return 2;
    }
    avsi::detail::run_server();
}
