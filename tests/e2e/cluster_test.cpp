// A real Slurm cluster (ctest label `cluster`): one node on localhost, run
// by this test from files it writes in a temporary folder — a munge key and
// munged on its own socket, slurm.conf (proctrack/linuxproc, task/none, no
// cgroups, state and spool folders, pid and log files all in the folder,
// free ports) with slurmctld and slurmd in the foreground as root. The
// array `avsi build-stimuli --slurm-script` writes for the shards test
// protocol (4 build tasks and the dependent merge) is submitted with its
// submit script, waited for with a bound, and the merged set is checked:
// every task and the merge completed, the merge's --verify passed, and
// --verify passes again here. The daemons are stopped whatever happens
// (and die with this process: PR_SET_PDEATHSIG). Where they cannot start
// (not root, Slurm or munge not installed, a daemon that does not come up),
// the test is skipped with the reason and the daemon's log.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fcntl.h>
#include <fstream>
#include <functional>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const fs::path protocol = fs::path(AVSI_TEST_DATA_DIR) / "stimuli" / "shards" / "protocol.toml";

// The program's path, searched in PATH and the sbin folders ("" if absent).
std::string find_program(const std::string& name) {
    std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
    path += ":/usr/sbin:/sbin:/usr/local/sbin";
    std::size_t start = 0;
    while (start <= path.size()) {
        const std::size_t colon = std::min(path.find(':', start), path.size());
        const fs::path candidate = fs::path(path.substr(start, colon - start)) / name;
        if (colon > start && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
        start = colon + 1;
    }
    return "";
}

// A TCP port on 127.0.0.1 that nothing listens on now.
int free_port() {
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    socklen_t length = sizeof a;
    int port = 0;
    if (s >= 0 && ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
        ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &length) == 0)
        port = ntohs(a.sin_port);
    if (s >= 0) ::close(s);
    return port;
}

// The last lines of a log, for a message.
std::string tail(const fs::path& log, std::size_t lines = 15) {
    std::string text = fs::exists(log) ? read_text_file(log) : "";
    std::size_t at = text.size();
    for (std::size_t n = 0; n <= lines && at > 0; ++n) at = text.rfind('\n', at - 1);
    return at == std::string::npos ? text : text.substr(at + 1);
}

// Waits until `ready()` or `seconds` have passed; true when ready.
bool wait_for(double seconds, const std::function<bool()>& ready, double poll_s = 0.25) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < until) {
        if (ready()) return true;
        std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
    }
    return ready();
}

// munged, slurmctld and slurmd of a one-node cluster in `dir`.
class LocalSlurm {
public:
    explicit LocalSlurm(fs::path dir) : m_dir(std::move(dir)) {}
    LocalSlurm(const LocalSlurm&) = delete;
    LocalSlurm& operator=(const LocalSlurm&) = delete;
    ~LocalSlurm() { stop(); }

    // Writes the files and starts the daemons; "" when the cluster is up,
    // else why it is not.
    std::string start() {
        if (::geteuid() != 0) return "the test runs slurmd, which launches jobs, as root; this process is not root";
        for (const char* program : {"munged", "slurmctld", "slurmd", "sbatch", "squeue", "scontrol", "scancel", "sinfo"})
            if (find_program(program).empty())
                return std::string(program) +
                       " is not installed (Debian's slurmctld, slurmd, slurm-client and munge; scripts/install-deps "
                       "installs them)";
        fs::create_directories(m_dir / "munge");
        fs::create_directories(m_dir / "state");
        fs::create_directories(m_dir / "spool");
        fs::create_directories(m_dir / "log");
        // munged wants its socket's folders searchable by all and its key readable by itself alone.
        for (const fs::path& p : {m_dir.parent_path(), m_dir, m_dir / "munge"}) ::chmod(p.c_str(), 0755);
        write_munge_key();
        const std::string node_line = node_description();
        if (node_line.empty()) return "`slurmd -C` did not describe this machine";
        write_slurm_conf(node_line);
        if (const std::string why = start_munge(); !why.empty()) return why;
        if (const std::string why = start_slurmctld(); !why.empty()) return why;
        return start_slurmd();
    }

    // Cancels every job of this cluster, then ends the daemons it started
    // (SIGTERM, SIGKILL after 10 s), each by its process id.
    void stop() {
        if (alive(m_slurmctld)) run("scancel --user=root --quiet");
        for (pid_t* pid : {&m_slurmd, &m_slurmctld, &m_munged}) {
            if (!alive(*pid)) continue;  // not started, or already ended and reaped
            ::kill(*pid, SIGTERM);
            if (!wait_for(10.0, [&] { return !alive(*pid); }, 0.1)) {
                ::kill(*pid, SIGKILL);
                int status = 0;
                ::waitpid(*pid, &status, 0);
                *pid = 0;
            }
        }
    }

    // A command line with SLURM_CONF pointing at this cluster, ended after
    // 60 s (a client waiting for a controller that stopped answering).
    test::CliResult run(const std::string& command) const {
        return test::run_command("SLURM_CONF=" + test::shell_quote(conf().string()) + " timeout 60 " + command);
    }
    fs::path conf() const { return m_dir / "slurm.conf"; }
    fs::path log(const std::string& daemon) const { return m_dir / "log" / (daemon + ".log"); }

private:
    void write_munge_key() const {
        std::random_device random;
        std::string key(1024, '\0');
        for (char& c : key) c = static_cast<char>(random() & 0xff);
        const fs::path path = m_dir / "munge" / "munge.key";
        write_text_file(path, key);
        ::chmod(path.c_str(), 0400);
    }

    // This machine's CPUs, boards, sockets, cores and threads as slurmd sees
    // them, with RealMemory capped at 2000 MB (the tasks ask for 300 MB).
    std::string node_description() const {
        const test::CliResult r = test::run_command(test::shell_quote(find_program("slurmd")) + " -C");
        std::smatch m;
        const std::string out = r.out;
        if (r.exit_code != 0 || !std::regex_search(out, m, std::regex("NodeName=\\S+ (CPUs=[^\\n]*)"))) return "";
        std::string line = m[1].str();
        std::smatch memory;
        if (std::regex_search(line, memory, std::regex("RealMemory=(\\d+)"))) {
            const long mb = std::min(std::stol(memory[1].str()), 2000L);
            line = std::regex_replace(line, std::regex("RealMemory=\\d+"), "RealMemory=" + std::to_string(mb));
        }
        return line;
    }

    void write_slurm_conf(const std::string& node_line) {
        char host[256] = {};
        ::gethostname(host, sizeof host - 1);
        m_node = std::string(host).substr(0, std::string(host).find('.'));
        const std::string d = m_dir.string();
        std::string conf = "# A one-node Slurm cluster for avsi's cluster test (tests/e2e/cluster_test.cpp).\n";
        conf += "ClusterName=avsitest\n";
        conf += "SlurmctldHost=" + m_node + "(127.0.0.1)\n";
        conf += "SlurmctldPort=" + std::to_string(free_port()) + "\n";
        conf += "SlurmdPort=" + std::to_string(free_port()) + "\n";
        conf += "SlurmUser=root\nSlurmdUser=root\n";
        conf += "AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket=" + d + "/munge/munge.socket\n";
        conf += "StateSaveLocation=" + d + "/state\nSlurmdSpoolDir=" + d + "/spool\n";
        conf += "SlurmctldPidFile=" + d + "/slurmctld.pid\nSlurmdPidFile=" + d + "/slurmd.pid\n";
        conf += "SlurmctldLogFile=" + d + "/log/slurmctld.log\nSlurmdLogFile=" + d + "/log/slurmd.log\n";
        conf += "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n";
        conf += "SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\nSchedulerType=sched/builtin\n";
        conf += "AccountingStorageType=accounting_storage/none\nJobCompType=jobcomp/none\nMpiDefault=none\n";
        conf += "ReturnToService=2\nMinJobAge=600\nSlurmctldTimeout=30\nSlurmdTimeout=30\nInactiveLimit=0\n";
        conf += "NodeName=" + m_node + " NodeAddr=127.0.0.1 " + node_line + " State=UNKNOWN\n";
        conf += "PartitionName=avsi Nodes=ALL Default=YES MaxTime=30 State=UP\n";
        write_text_file(m_dir / "slurm.conf", conf);
    }

    // Starts `args` in the foreground of a child process of its own, output
    // to `log`, ended with this process if it dies first.
    static pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
        const pid_t pid = ::fork();
        if (pid == 0) {
            ::prctl(PR_SET_PDEATHSIG, SIGTERM);
            ::setpgid(0, 0);
            const int out = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            ::dup2(out, 1);
            ::dup2(out, 2);
            std::vector<char*> argv;
            for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
            argv.push_back(nullptr);
            ::execv(argv[0], argv.data());
            ::_exit(127);
        }
        return pid;
    }

    // Whether the child `pid` still runs; once it has ended (and is reaped
    // here) `pid` is set to 0, so no signal can reach a process that reuses its id.
    static bool alive(pid_t& pid) {
        if (pid <= 0) return false;
        int status = 0;
        if (::waitpid(pid, &status, WNOHANG) == 0) return true;
        pid = 0;
        return false;
    }

    std::string start_munge() {
        const std::string d = m_dir.string() + "/munge";
        m_munged = spawn({find_program("munged"), "--foreground", "--socket=" + d + "/munge.socket",
                          "--key-file=" + d + "/munge.key", "--pid-file=" + d + "/munged.pid",
                          "--seed-file=" + d + "/munged.seed", "--log-file=" + d + "/munged.log"},
                         log("munged"));
        if (!wait_for(10.0, [&] { return !alive(m_munged) || fs::exists(d + "/munge.socket"); }) || !alive(m_munged))
            return "munged did not start: " + tail(log("munged"));
        return "";
    }

    std::string start_slurmctld() {
        m_slurmctld = spawn({find_program("slurmctld"), "-D", "-i", "-f", conf().string()}, log("slurmctld.out"));
        if (!wait_for(20.0, [&] { return !alive(m_slurmctld) || run("scontrol ping").out.find("UP") != std::string::npos; }) ||
            !alive(m_slurmctld))
            return "slurmctld did not start: " + tail(log("slurmctld.out"));
        return "";
    }

    std::string start_slurmd() {
        m_slurmd = spawn({find_program("slurmd"), "-D", "-f", conf().string(), "-N", m_node}, log("slurmd.out"));
        const auto idle = [&] {
            const std::string state = run("sinfo -h -N -o %T").out;
            return state.find("idle") != std::string::npos || state.find("mixed") != std::string::npos;
        };
        if (!wait_for(30.0, [&] { return !alive(m_slurmd) || idle(); }) || !alive(m_slurmd))
            return "slurmd did not start or its node did not come up: " + tail(log("slurmd.out")) +
                   run("sinfo -N -l").output();
        return "";
    }

    fs::path m_dir;
    std::string m_node;
    pid_t m_munged = 0, m_slurmctld = 0, m_slurmd = 0;
};

// The job id after `label` in the submit script's output ("array job 3: …").
std::string job_id(const std::string& output, const std::string& label) {
    std::smatch m;
    return std::regex_search(output, m, std::regex(label + " job (\\d+)")) ? m[1].str() : "";
}

TEST(Cluster, SlurmArrayOfFourShardsAndItsMergeBuildAVerifiedSet) {
    const fs::path dir = test::temp_dir("cluster");
    LocalSlurm slurm(dir / "slurm");
    if (const std::string why = slurm.start(); !why.empty()) {
        slurm.stop();
        GTEST_SKIP() << "no local Slurm cluster: " << why;
    }

    // The scripts, as a user writes them.
    const fs::path set = dir / "set";
    const test::CliResult written =
        test::run_avsi({"build-stimuli", protocol.string(), "--out", set.string(), "--slurm-script",
                        (dir / "job.sbatch").string(), "--shards", "4", "--time", "00:10:00", "--mem", "300M", "--cpus",
                        "1"});
    ASSERT_EQ(written.exit_code, 0) << written.output();

    const test::CliResult submitted = slurm.run(test::shell_quote((dir / "job.submit.sh").string()));
    ASSERT_EQ(submitted.exit_code, 0) << submitted.output();
    const std::string array = job_id(submitted.out, "array"), merge = job_id(submitted.out, "merge");
    ASSERT_FALSE(array.empty() || merge.empty()) << submitted.output();

    // Wait (bounded) until neither the array nor the merge is queued or running.
    const bool finished = wait_for(
        300.0, [&] { return slurm.run("squeue -h -j " + array + "," + merge + " -o %i").out.empty(); }, 1.0);
    const std::string jobs = slurm.run("scontrol -o show job " + array).out + slurm.run("scontrol -o show job " + merge).out;
    ASSERT_TRUE(finished) << "the jobs did not finish within 300 s:\n" << slurm.run("squeue").output() << jobs;

    // Four tasks and the merge (one line each), each completed with exit code 0.
    const std::regex state("^JobId=(\\d+) (?:ArrayJobId=\\d+ ArrayTaskId=(\\d+) )?.*? JobState=(\\S+) .*? ExitCode=(\\S+)");
    std::size_t tasks = 0, merges = 0;
    std::istringstream lines(jobs);
    for (std::string line; std::getline(lines, line);) {
        std::smatch m;
        if (!std::regex_search(line, m, state)) continue;
        SCOPED_TRACE(line.substr(0, 300));
        EXPECT_EQ(m[3].str(), "COMPLETED");
        EXPECT_EQ(m[4].str(), "0:0");
        ++(m[2].matched ? tasks : merges);
    }
    EXPECT_EQ(tasks, 4u) << jobs;
    EXPECT_EQ(merges, 1u) << jobs;

    for (std::size_t k = 0; k < 4; ++k) EXPECT_TRUE(fs::exists(set / "shards" / fmt::format("shard-{}-of-4.json", k)));
    std::string merge_log;
    for (const auto& entry : fs::directory_iterator(set / "slurm"))
        if (entry.path().filename().string().find("-merge-") != std::string::npos) merge_log = read_text_file(entry.path());
    EXPECT_NE(merge_log.find("verified 12 stimuli"), std::string::npos) << merge_log;
    ASSERT_TRUE(fs::exists(set / "manifest.json")) << merge_log;
    const test::CliResult verified = test::run_avsi({"build-stimuli", protocol.string(), "--out", set.string(), "--verify"});
    EXPECT_EQ(verified.exit_code, 0) << verified.output();
    EXPECT_NE(verified.out.find("verified 12 stimuli"), std::string::npos) << verified.output();

    slurm.stop();
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi
