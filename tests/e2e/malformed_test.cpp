// The malformed-input corpus (tests/data/malformed/<format>/, issue 19): every
// case goes through the avsi command line in a child process with a CPU-time
// and address-space limit, and must exit 1 with a compiler-style error whose
// first line equals the case's golden .err (AVSI_UPDATE_GOLDEN=1 rewrites
// them): the file named, no crash, no hang, no huge allocation.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <fstream>
#include <ostream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "avsi/core/files.h"
#include "avsi/core/text.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

const fs::path k_corpus = fs::path(AVSI_TEST_DATA_DIR) / "malformed";
// Limits per case: CPU seconds, wall seconds, address space, resident
// memory above the executable's baseline.
constexpr int k_cpu_s = 20;
constexpr int k_wall_s = 60;
constexpr rlim_t k_address_space_bytes = rlim_t{4} << 30;
constexpr long k_max_rss_kib = 300 * 1024;
// The cases whose header claims 10⁹ items must stay under 100 MB above the
// baseline (issue 19).
constexpr long k_huge_header_rss_kib = 100 * 1024;

struct Case {
    std::string format;
    fs::path file;
    std::string name() const {
        std::string n = format + "_" + file.stem().string();
        for (char& c : n)
            if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
        return n;
    }
};

std::vector<Case> all_cases() {
    std::vector<Case> out;
    if (!fs::is_directory(k_corpus)) return out;
    for (const auto& dir : fs::directory_iterator(k_corpus)) {
        if (!dir.is_directory() || dir.path().filename().string().front() == '_') continue;  // _support
        for (const auto& f : fs::directory_iterator(dir.path())) {
            const std::string ext = f.path().extension().string();
            const std::string name = f.path().filename().string();
            if (ext == ".err" || name == "command" || name == "README.md" || f.is_directory()) continue;
            out.push_back({dir.path().filename().string(), f.path()});
        }
    }
    std::sort(out.begin(), out.end(), [](const Case& a, const Case& b) { return a.file < b.file; });
    return out;
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
    if (from.empty()) return s;
    for (std::size_t p = 0; (p = s.find(from, p)) != std::string::npos; p += to.size()) s.replace(p, from.size(), to);
    return s;
}

struct Outcome {
    int exit_code = -1;
    int signal = 0;
    bool timed_out = false;
    long max_rss_kib = 0;
    std::string err;
};

// Runs avsi with `args` under the limits; stderr to `err_path`.
Outcome run_limited(const std::vector<std::string>& args, const fs::path& err_path, const fs::path& cwd) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        const rlimit cpu{k_cpu_s, k_cpu_s};
        const rlimit as{k_address_space_bytes, k_address_space_bytes};
        const rlimit core{0, 0};
        ::setrlimit(RLIMIT_CPU, &cpu);
        ::setrlimit(RLIMIT_AS, &as);
        ::setrlimit(RLIMIT_CORE, &core);
        const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int null = ::open("/dev/null", O_RDWR);
        ::dup2(null, 0);
        ::dup2(null, 1);
        ::dup2(err, 2);
        if (::chdir(cwd.c_str()) != 0) ::_exit(126);
        std::vector<char*> argv{const_cast<char*>(AVSI_CLI_PATH)};
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        ::execv(AVSI_CLI_PATH, argv.data());
        ::_exit(127);
    }
    Outcome o;
    int status = 0;
    rusage usage{};
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(k_wall_s);
    for (;;) {
        const pid_t done = ::wait4(pid, &status, WNOHANG, &usage);
        if (done == pid) break;
        if (std::chrono::steady_clock::now() > deadline) {
            ::kill(pid, SIGKILL);
            ::wait4(pid, &status, 0, &usage);
            o.timed_out = true;
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    o.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    o.max_rss_kib = usage.ru_maxrss;
    o.err = read_text_file(err_path);
    return o;
}

// gtest prints a parameter with this (instead of its bytes).
void PrintTo(const Case& c, std::ostream* os) { *os << c.file.string(); }

// The peak resident memory of `avsi --version`: what the executable takes
// before reading anything (its libraries), measured once.
// The peak memory of the helper a command runs in, doing nothing: `avsi
// <command> --help` (the front end runs each command in a helper that loads
// that group's libraries, 4 MiB to 280 MiB before it reads anything).
long baseline_rss_kib(const std::string& command) {
    static std::map<std::string, long> cache;
    const auto it = cache.find(command);
    if (it != cache.end()) return it->second;
    const fs::path dir = fs::path(::testing::TempDir()) / "avsi_malformed_baseline";
    fs::create_directories(dir);
    const long rss = run_limited({command, "--help"}, dir / "stderr.txt", dir).max_rss_kib;
    cache[command] = rss;
    return rss;
}

class Malformed : public ::testing::TestWithParam<Case> {};

TEST_P(Malformed, ExitsOneNamingTheFileWithinLimits) {
    const Case& c = GetParam();
    const fs::path work = fs::path(::testing::TempDir()) / ("avsi_malformed_" + c.name());
    fs::remove_all(work);
    const fs::path in_dir = work / "in", out_dir = work / "out";
    fs::create_directories(in_dir);
    fs::create_directories(out_dir);

    // The format's command file: `copy FILE` (into the input folder), `name
    // NAME` (the case is copied there under that name), `args …` (the avsi
    // arguments; {input}, {dir}, {out}, {data} are replaced).
    const fs::path command_file = k_corpus / c.format / "command";
    ASSERT_TRUE(fs::exists(command_file)) << "no command file for format " << c.format;
    fs::path input = c.file;
    std::vector<std::string> args;
    auto expand = [&](std::string s) {
        s = replace_all(s, "{input}", input.string());
        s = replace_all(s, "{dir}", in_dir.string());
        s = replace_all(s, "{out}", out_dir.string());
        s = replace_all(s, "{data}", AVSI_TEST_DATA_DIR);
        return s;
    };
    std::istringstream lines(read_text_file(command_file));
    for (std::string line; std::getline(lines, line);) {
        line = trim(line);
        if (line.empty() || line[0] == '#') continue;
        const auto space = line.find(' ');
        const std::string key = line.substr(0, space), value = space == std::string::npos ? "" : trim(line.substr(space));
        if (key == "copy") {
            const fs::path from = expand(value);
            fs::copy(from, in_dir / from.filename(), fs::copy_options::recursive | fs::copy_options::overwrite_existing);
        } else if (key == "name") {
            input = in_dir / value;
            fs::create_directories(input.parent_path());
            fs::copy_file(c.file, input, fs::copy_options::overwrite_existing);
        } else if (key == "args") {
            std::istringstream words(value);
            for (std::string w; words >> w;) args.push_back(expand(w));
        }
    }
    ASSERT_FALSE(args.empty()) << command_file << " has no args line";
    const Outcome o = run_limited(args, work / "stderr.txt", work);
    SCOPED_TRACE("stderr: " + o.err);
    EXPECT_FALSE(o.timed_out) << "no result within " << k_wall_s << " s";
    EXPECT_EQ(o.signal, 0) << "killed by signal " << o.signal;
    EXPECT_EQ(o.exit_code, 1);
    const bool huge_header = c.file.stem().string().find("huge") != std::string::npos;
    const long baseline_kib = baseline_rss_kib(args.front());
    EXPECT_LE(o.max_rss_kib - baseline_kib, huge_header ? k_huge_header_rss_kib : k_max_rss_kib)
        << "peak resident memory above the command's helper doing nothing (" << baseline_kib << " KiB)";

    // The first error line, with the temporary and data folders as placeholders.
    std::string first;
    std::istringstream err_lines(o.err);
    for (std::string line; std::getline(err_lines, line);)
        if (line.find("error: ") != std::string::npos) {
            first = line;
            break;
        }
    ASSERT_FALSE(first.empty()) << "no error line";
    first = replace_all(first, in_dir.string(), "{dir}");
    first = replace_all(first, out_dir.string(), "{out}");
    first = replace_all(first, std::string(AVSI_TEST_DATA_DIR), "{data}");
    // A file is named first: the case itself, the copy it was given as, or
    // a file the case points to (a corpus manifest's labels).
    const std::string named = first.substr(0, first.find(": error: "));
    EXPECT_TRUE(named.find(c.file.filename().string()) != std::string::npos ||
                named.find(input.filename().string()) != std::string::npos || named.rfind("{dir}/", 0) == 0)
        << "the error does not name " << c.file.filename();
    const fs::path golden = fs::path(c.file).replace_extension(".err");
    if (std::getenv("AVSI_UPDATE_GOLDEN")) {
        write_text_file(golden, first + "\n");
    } else {
        ASSERT_TRUE(fs::exists(golden)) << "no golden " << golden << " (AVSI_UPDATE_GOLDEN=1 writes it)";
        EXPECT_EQ(first, trim(read_text_file(golden)));
    }
    fs::remove_all(work);
}

INSTANTIATE_TEST_SUITE_P(Corpus, Malformed, ::testing::ValuesIn(all_cases()),
                         [](const ::testing::TestParamInfo<Case>& info) { return info.param.name(); });

TEST(MalformedCorpus, HasAtLeast150CasesAcrossTheFormats) {
    const auto cases = all_cases();
    std::set<std::string> formats;
    for (const auto& c : cases) formats.insert(c.format);
    EXPECT_GE(cases.size(), 150u);
    EXPECT_GE(formats.size(), 12u);
}

}  // namespace
}  // namespace avsi
