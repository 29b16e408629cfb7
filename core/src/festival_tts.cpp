// Festival through its C++ library, run in a process of its own: the
// avsi-festival executable (festival_server.cpp), started by the first
// Festival call of this process, so that neither Festival's global state nor
// its libraries ever touch the caller. This file is the caller's side: it
// starts the server, sends it requests and reads the answers. See docs/tts.md
// ("Festival").
#include "festival_tts.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/executable_folder.h"
#include "festival_protocol.h"
#include "wire.h"

namespace avsi::detail {

namespace {

namespace proto = festival_protocol;

struct Request {
    std::int64_t kind = 0;
    std::string voice;
    std::string text;
};

// The avsi-festival executable, first found of: $AVSI_EXEC_PATH (as the front
// end looks for its helpers), beside this executable (the helpers in
// build/cli/libexec or an installed libexec/avsi), the build tree's (tests
// and benchmarks). Throws, naming where it looked, if none is there.
std::string server_path() {
    std::vector<std::string> candidates;
    if (const char* env = std::getenv("AVSI_EXEC_PATH"); env && *env) candidates.push_back(std::string(env) + "/avsi-festival");
    if (const std::string own = executable_folder(); !own.empty()) candidates.push_back(own + "/avsi-festival");
    if (std::find(candidates.begin(), candidates.end(), AVSI_FESTIVAL_SERVER_BUILD_PATH) == candidates.end())
        candidates.emplace_back(AVSI_FESTIVAL_SERVER_BUILD_PATH);
    for (const auto& path : candidates)
        if (::access(path.c_str(), X_OK) == 0) return path;
    std::string list;
    for (const auto& path : candidates) list += (list.empty() ? "" : ", ") + path;
    throw std::runtime_error(fmt::format(
        "festival: the Festival server avsi-festival is not at any of {} (build avsi's targets, or set "
        "AVSI_EXEC_PATH to the folder that holds it)",
        list));
}

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
        const std::string path = server_path();
        int sv[2];
        if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0)
            throw std::runtime_error(fmt::format("festival: socketpair failed: {}", std::strerror(errno)));
        const pid_t pid = ::fork();
        if (pid < 0) {
            ::close(sv[0]);
            ::close(sv[1]);
            throw std::runtime_error(fmt::format("festival: fork failed: {}", std::strerror(errno)));
        }
        if (pid == 0) exec_server(path, sv[1]);
        ::close(sv[1]);
        m_socket = sv[0];
        m_pid = pid;
        // Wait for festival_initialize (a fraction of a second; a minute is a hang).
        pollfd p{m_socket, POLLIN, 0};
        char ready = 0;
        int polled;
        do polled = ::poll(&p, 1, 60'000);
        while (polled < 0 && errno == EINTR);
        if (polled <= 0 || ::recv(m_socket, &ready, 1, 0) != 1 || ready != proto::k_ready) {
            stop();
            throw std::runtime_error(fmt::format(
                "festival: Festival could not be initialised by {} (are the festival and festvox-us-slt-hts "
                "packages installed? scripts/install-deps installs them)",
                path));
        }
    }

    // In the forked child: the server with only its socket open, as
    // descriptor 3, and stdin/stdout/stderr on /dev/null (a descriptor of the
    // caller's kept open there, such as a pipe's write end, would never let
    // its reader finish). Only async-signal-safe calls: the caller may have
    // threads.
    [[noreturn]] static void exec_server(const std::string& path, int socket_fd) {
        if (socket_fd == proto::k_server_fd) {
            ::fcntl(socket_fd, F_SETFD, 0);  // dup2 onto itself would keep close-on-exec
        } else {
            ::dup2(socket_fd, proto::k_server_fd);  // without close-on-exec
        }
        const int null_fd = ::open("/dev/null", O_RDWR | O_CLOEXEC);
        if (null_fd >= 0)
            for (int fd = 0; fd <= 2; ++fd) ::dup2(null_fd, fd);
        if (::close_range(proto::k_server_fd + 1, ~0U, 0) != 0)  // kernels before 5.9
            for (int fd = proto::k_server_fd + 1; fd < 65536; ++fd) ::close(fd);
        char* const argv[] = {const_cast<char*>("avsi-festival"), nullptr};
        ::execv(path.c_str(), argv);
        ::_exit(127);
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
    if (status == proto::UnknownVoice) {
        std::vector<std::string> installed(reader.count(sizeof(std::int64_t)));
        for (auto& v : installed) v = reader.str();
        std::string list;
        for (const auto& v : installed) list += (list.empty() ? "" : ", ") + v;
        const std::string close = closest_match(r.voice, installed);
        throw InputError("tts", 0, 0, "voice",
                         fmt::format("unknown Festival voice \"{}\"{}; installed Festival voices: {}", r.voice,
                                     close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close),
                                     list.empty() ? "none (install festvox-us-slt-hts)" : list));
    }
    if (status != proto::Ok) throw std::runtime_error(reader.str());
    return answer.substr(sizeof(std::int64_t));
}

}  // namespace

FestivalUtterance festival_synthesize(const std::string& text, const std::string& voice) {
    if (text.size() > proto::k_max_text_bytes)
        throw InputError("tts", 0, 0, "text",
                         fmt::format("expected at most {} bytes of text for Festival, got {}", proto::k_max_text_bytes,
                                     text.size()));
    const std::string answer = call_ok({proto::Synthesize, voice, text});
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
    const std::string answer = call_ok({proto::ListVoices, "", ""});
    WireReader reader(answer, "festival answer");
    std::vector<std::string> voices(reader.count(sizeof(std::int64_t)));
    for (auto& v : voices) v = reader.str();
    return voices;
}

std::pair<std::string, std::vector<FestivalWord>> festival_transcribe(const std::vector<std::string>& words,
                                                                      const std::string& voice) {
    std::string text;
    for (const auto& word : words) {
        if (word.find('\n') != std::string::npos || word.empty())
            throw std::invalid_argument("festival_transcribe: a word is empty or holds a newline");
        text += word + '\n';
    }
    if (text.size() > proto::k_max_text_bytes)
        throw InputError("tts", 0, 0, "text",
                         fmt::format("expected at most {} bytes of words for Festival, got {}", proto::k_max_text_bytes,
                                     text.size()));
    const std::string answer = call_ok({proto::Transcribe, voice, text});
    WireReader reader(answer, "festival answer");
    std::pair<std::string, std::vector<FestivalWord>> out;
    out.first = reader.str();
    out.second.resize(reader.count(2 * sizeof(std::int64_t)));
    for (auto& word : out.second) {
        word.in_lexicon = reader.i64() != 0;
        word.phones.resize(reader.count(2 * sizeof(std::int64_t)));
        for (auto& p : word.phones) {
            p.name = reader.str();
            p.stressed = reader.i64() != 0;
        }
    }
    if (out.second.size() != words.size())
        throw std::runtime_error(fmt::format("festival: {} transcriptions for {} words", out.second.size(), words.size()));
    return out;
}

FestivalVoiceInfo festival_voice_info(const std::string& voice) {
    const std::string answer = call_ok({proto::VoiceInfo, voice, ""});
    WireReader reader(answer, "festival answer");
    FestivalVoiceInfo info;
    info.festival_version = reader.str();
    info.voice = reader.str();
    info.directory = reader.str();
    return info;
}

}  // namespace avsi::detail
