#include "process_harness.hpp"

#include <fcntl.h>
#include <sched.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "peer_protocol.hpp"

extern char** environ;

namespace vslam::transport_test {
namespace {

using SteadyClock = std::chrono::steady_clock;

constexpr const char* kNetnsEnv = "VSLAM_TRANSPORT_NETNS";
constexpr const char* kResultEnv = "VSLAM_TRANSPORT_RESULT";
// Exit code of the namespace set-up script when `ip` fails.
constexpr int kNetnsSetupFailed = 97;

std::string findInPath(const std::string& name) {
  if (name.find('/') != std::string::npos) return name;
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const std::string candidate = dir + "/" + name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  // Debian keeps ip in /usr/sbin, which a non-login PATH may lack.
  for (const char* dir2 : {"/usr/sbin", "/sbin"}) {
    const std::string candidate = std::string(dir2) + "/" + name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return name;
}

void skipCurrentTest(const std::string& why) { GTEST_SKIP() << why; }

}  // namespace

// ---- Child -----------------------------------------------------------------------

Child Child::spawn(const std::vector<std::string>& argv,
                   const std::vector<std::pair<std::string, std::string>>& extra_env,
                   const std::string& stdout_file) {
  Child child;
  if (argv.empty()) return child;
  const std::string exe = findInPath(argv[0]);

  // Everything the child needs is prepared before fork(): after it, only
  // async-signal-safe calls (the test process may have LCM threads).
  std::vector<std::string> env_strings;
  std::map<std::string, std::string> overrides(extra_env.begin(), extra_env.end());
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    const std::string key = entry.substr(0, entry.find('='));
    if (overrides.count(key) == 0) env_strings.push_back(entry);
  }
  for (const auto& [k, v] : overrides) env_strings.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (auto& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::vector<std::string> args = argv;
  std::vector<char*> argvp;
  for (auto& s : args) argvp.push_back(s.data());
  argvp.push_back(nullptr);

  int out_fd = -1;
  if (!stdout_file.empty()) {
    out_fd = open(stdout_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  }
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid == 0) {
    // Dies with the test, whatever kills it (a CTest timeout included).
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    if (out_fd >= 0) {
      dup2(out_fd, STDOUT_FILENO);
      dup2(out_fd, STDERR_FILENO);
    }
    execve(exe.c_str(), argvp.data(), envp.data());
    _exit(127);
  }
  if (out_fd >= 0) close(out_fd);
  child.pid_ = pid;
  return child;
}

Child& Child::operator=(Child&& other) noexcept {
  if (this != &other) {
    kill();
    pid_ = other.pid_;
    status_ = other.status_;
    other.pid_ = -1;
    other.status_.reset();
  }
  return *this;
}

Child::~Child() { kill(); }

bool Child::running() {
  if (pid_ <= 0 || status_) return false;
  int st = 0;
  const pid_t r = waitpid(pid_, &st, WNOHANG);
  if (r == pid_) {
    status_ = st;
    return false;
  }
  return r == 0;
}

std::optional<int> Child::waitFor(double timeout_s) {
  const auto deadline = SteadyClock::now() + std::chrono::duration<double>(timeout_s);
  while (running()) {
    if (SteadyClock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return status_;
}

void Child::sendSignal(int sig) {
  if (pid_ > 0 && !status_) ::kill(pid_, sig);
}

void Child::kill() {
  if (pid_ > 0 && !status_) {
    ::kill(pid_, SIGKILL);
    int st = 0;
    if (waitpid(pid_, &st, 0) == pid_) status_ = st;
  }
}

std::string describeStatus(int st) {
  if (WIFEXITED(st)) return "exited with code " + std::to_string(WEXITSTATUS(st));
  if (WIFSIGNALED(st)) {
    return "killed by signal " + std::to_string(WTERMSIG(st)) + " (" + strsignal(WTERMSIG(st)) +
           ")";
  }
  return "wait status " + std::to_string(st);
}

bool exitedWith(const std::optional<int>& st, int code) {
  return st && WIFEXITED(*st) && WEXITSTATUS(*st) == code;
}

// ---- network namespace -----------------------------------------------------------

bool insideTestNetns() {
  const char* v = std::getenv(kNetnsEnv);
  return v && std::string(v) == "1";
}

bool enterFreshNetns() {
  if (insideTestNetns()) return true;

  // May this process create a network namespace at all? Probe in a child.
  const pid_t probe = fork();
  if (probe == 0) _exit(unshare(CLONE_NEWNET) == 0 ? 0 : (errno & 0xff));
  int st = 0;
  waitpid(probe, &st, 0);
  if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
    const int err = WIFEXITED(st) ? WEXITSTATUS(st) : 0;
    skipCurrentTest(
        std::string("cannot create a private network namespace: unshare(CLONE_NEWNET): ") +
        (err ? std::strerror(err) : describeStatus(st)) +
        " (needs root or CAP_SYS_ADMIN); multicast tests are not run outside one so "
        "that they cannot disturb, or be disturbed by, other LCM traffic");
    return false;
  }

  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n <= 0) {
    ADD_FAILURE() << "cannot read /proc/self/exe";
    return false;
  }
  self[n] = '\0';
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test_name = std::string(info->test_suite_name()) + "." + info->name();

  TempDir dir;
  const std::string result_file = dir.path() + "/result";
  const std::string script =
      "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || "
      "{ echo 'private network namespace: ip set-up failed' >&2; exit " +
      std::to_string(kNetnsSetupFailed) + "; }; exec \"$@\"";
  const std::string ip_dir = std::filesystem::path(findInPath("ip")).parent_path().string();
  const char* path_env = std::getenv("PATH");
  Child inner = Child::spawn(
      {"unshare", "--net", "sh", "-c", script, "sh", self, "--gtest_filter=" + test_name},
      {{kNetnsEnv, "1"},
       {kResultEnv, result_file},
       {"PATH", std::string(path_env ? path_env : "/usr/bin:/bin") + ":" + ip_dir}});
  if (!inner.valid()) {
    ADD_FAILURE() << "fork failed: " << std::strerror(errno);
    return false;
  }
  // The CTest TIMEOUT bounds this; the inner process dies with us.
  const std::optional<int> status = inner.waitFor(3600);
  std::string result;
  {
    std::ifstream in(result_file);
    std::getline(in, result);
  }
  if (!exitedWith(status, 0)) {
    ADD_FAILURE() << "the test run in a private network namespace "
                  << (status ? describeStatus(*status) : std::string("did not finish"))
                  << (exitedWith(status, kNetnsSetupFailed)
                          ? " (namespace set-up with `ip` failed, see its output above)"
                          : " (see its output above)");
  } else if (result == "skipped") {
    skipCurrentTest("skipped inside the private network namespace (reason above)");
  } else if (result != "passed") {
    ADD_FAILURE() << "the run in the private network namespace exited 0 but reported '" << result
                  << "' for " << test_name << " (did --gtest_filter match it?)";
  }
  return false;
}

void NetnsTest::TearDown() {
  if (!insideTestNetns()) return;
  const char* file = std::getenv(kResultEnv);
  if (!file) return;
  std::ofstream out(file);
  out << (IsSkipped() ? "skipped" : HasFailure() ? "failed" : "passed") << "\n";
}

// ---- TestBus -----------------------------------------------------------------------

TestBus::TestBus(const std::string& url) : lcm_(std::make_unique<lcm::LCM>(url)) {
  if (!lcm_->good()) return;
  subscribe(kHelloChannel, [this](const std::string&, const uint8_t* data, size_t size) {
    ++hello_count_;
    if (auto_ack_) lcm_->publish(kAckChannel, data, static_cast<unsigned>(size));
  });
  subscribe(kDoneChannel, [this](const std::string&, const uint8_t* data, size_t size) {
    done_counts_.push_back(
        std::atoi(std::string(reinterpret_cast<const char*>(data), size).c_str()));
  });
}

TestBus::~TestBus() = default;

void TestBus::subscribe(const std::string& channel_regex, RawHandler handler, int queue_capacity) {
  auto h = std::make_unique<Handler>();
  h->fn = std::move(handler);
  lcm::Subscription* sub = lcm_->subscribeFunction(channel_regex, &Handler::onMessage, h.get());
  if (sub) sub->setQueueCapacity(queue_capacity);
  handlers_.push_back(std::move(h));
}

void TestBus::record(const std::string& channel_regex, int queue_capacity) {
  subscribe(
      channel_regex,
      [this](const std::string& channel, const uint8_t* data, size_t size) {
        received_.push_back({channel, std::vector<uint8_t>(data, data + size)});
      },
      queue_capacity);
}

bool TestBus::spinUntil(const std::function<bool()>& pred, double timeout_s) {
  const auto deadline = SteadyClock::now() + std::chrono::duration<double>(timeout_s);
  while (!pred()) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now());
    if (left.count() <= 0) return pred();
    lcm_->handleTimeout(static_cast<int>(std::min<int64_t>(left.count(), 20)));
  }
  return true;
}

void TestBus::spinFor(double seconds) {
  spinUntil([] { return false; }, seconds);
}

void TestBus::publishRaw(const std::string& channel, const std::vector<uint8_t>& bytes) {
  lcm_->publish(channel, bytes.data(), static_cast<unsigned>(bytes.size()));
}

std::optional<int> spinUntilPeerDone(TestBus& bus, Child& peer, double timeout_s) {
  const auto deadline = SteadyClock::now() + std::chrono::duration<double>(timeout_s);
  std::optional<SteadyClock::time_point> exited_at;
  const size_t dones_before = bus.doneCounts().size();
  while (SteadyClock::now() < deadline) {
    bus.lcm().handleTimeout(20);
    if (!exited_at && !peer.running()) exited_at = SteadyClock::now();
    if (exited_at) {
      if (bus.doneCounts().size() > dones_before) break;
      if (SteadyClock::now() - *exited_at > std::chrono::seconds(2)) break;
    }
  }
  // Whatever is still queued in LCM (DONE is the last message, but be generous).
  bus.spinFor(0.1);
  return peer.status();
}

// ---- TempDir -------------------------------------------------------------------------

TempDir::TempDir() {
  const char* tmp = std::getenv("TMPDIR");
  std::string pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/vslam-transport-XXXXXX";
  if (mkdtemp(pattern.data())) path_ = pattern;
}

TempDir::~TempDir() {
  if (path_.empty()) return;
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

}  // namespace vslam::transport_test
