#pragma once
// Test-side plumbing for the multi-process transport tests:
//  - Child: fork/exec a process that dies with the test (PR_SET_PDEATHSIG),
//    wait for it with a timeout, signal it; killed and reaped on destruction.
//  - Fresh network namespace per test: VSLAM_IN_FRESH_NETNS() re-runs the
//    current test (only it, via --gtest_filter) as
//      unshare --net sh -c 'ip link set lo up; ip link set lo multicast on;
//                           ip route add 224.0.0.0/4 dev lo; exec TEST_BINARY ...'
//    and reports the inner run's outcome (pass, fail or skip) as its own; it
//    skips the test when creating a network namespace is not permitted.
//  - TestBus: an lcm::LCM that records raw messages, answers the peers' HELLO
//    handshake, and spins handle() until a condition holds or a timeout.

#include <gtest/gtest.h>
#include <sys/types.h>

#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vslam::transport_test {

// ---- child processes -------------------------------------------------------

class Child {
 public:
  Child() = default;
  // argv[0] without a '/' is looked up in PATH. extra_env is added to the
  // environment. stdout_file, if not empty, receives the child's stdout and stderr.
  static Child spawn(const std::vector<std::string>& argv,
                     const std::vector<std::pair<std::string, std::string>>& extra_env = {},
                     const std::string& stdout_file = "");
  Child(Child&& other) noexcept { *this = std::move(other); }
  Child& operator=(Child&& other) noexcept;
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child();

  pid_t pid() const { return pid_; }
  bool valid() const { return pid_ > 0; }
  // True while the process has not exited (reaps it if it has).
  bool running();
  // Waits up to timeout_s; the raw wait status, or nullopt if still running.
  std::optional<int> waitFor(double timeout_s);
  std::optional<int> status() const { return status_; }
  void sendSignal(int sig);
  // SIGKILL and reap if still running.
  void kill();

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

// "exited with code N" / "killed by signal N (name)".
std::string describeStatus(int wait_status);
bool exitedWith(const std::optional<int>& wait_status, int code);

// ---- fresh network namespace per test -----------------------------------------

// True in the inner run (inside the private namespace).
bool insideTestNetns();
// In the outer run: runs the current test in a fresh namespace, records its
// outcome, returns false (the caller returns). Inside: returns true.
bool enterFreshNetns();

#define VSLAM_IN_FRESH_NETNS()                               \
  do {                                                       \
    if (!::vslam::transport_test::enterFreshNetns()) return; \
  } while (0)

// Fixture for namespace tests: in the inner run, writes the outcome for the
// outer run to read.
class NetnsTest : public ::testing::Test {
 protected:
  void TearDown() override;
};

// ---- LCM on the test side -------------------------------------------------------

struct ReceivedMessage {
  std::string channel;
  std::vector<uint8_t> bytes;
};

class TestBus {
 public:
  using RawHandler =
      std::function<void(const std::string& channel, const uint8_t* data, size_t size)>;

  explicit TestBus(const std::string& url);
  ~TestBus();
  bool good() const { return lcm_->good(); }
  lcm::LCM& lcm() { return *lcm_; }

  // Calls handler for every message on channels matching `channel_regex`.
  void subscribe(const std::string& channel_regex, RawHandler handler, int queue_capacity = 1000);
  // Stores every message on matching channels in received() (peers' handshake
  // and DONE channels excluded unless named explicitly).
  void record(const std::string& channel_regex, int queue_capacity = 1000);
  std::vector<ReceivedMessage>& received() { return received_; }

  // Answer HELLO with ACK (on by default).
  void setAutoAck(bool on) { auto_ack_ = on; }
  int helloCount() const { return hello_count_; }
  // DONE payloads seen (number of messages the peer published).
  const std::vector<int>& doneCounts() const { return done_counts_; }

  // Runs handle() until pred() holds or timeout_s passes; returns pred().
  bool spinUntil(const std::function<bool()>& pred, double timeout_s);
  void spinFor(double seconds);

  void publishRaw(const std::string& channel, const std::vector<uint8_t>& bytes);
  template <class Msg>
  void publish(const std::string& channel, const Msg& msg) {
    std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    publishRaw(channel, bytes);
  }

 private:
  // Subscribed with subscribeFunction (a plain function and a context): GCC 12
  // with -fsanitize=undefined miscompiles LCM 1.3.1's member-function
  // subscribe (its cb_func calls the handler with this == nullptr).
  struct Handler {
    RawHandler fn;
    static void onMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel,
                          Handler* self) {
      self->fn(channel, static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
    }
  };
  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<std::unique_ptr<Handler>> handlers_;
  std::vector<ReceivedMessage> received_;
  bool auto_ack_ = true;
  int hello_count_ = 0;
  std::vector<int> done_counts_;
};

// Waits for a peer started with Child::spawn to finish: spins the bus until
// the peer has exited and its DONE arrived (or 2 s after its exit), with an
// overall timeout. Returns the peer's wait status (nullopt on timeout).
std::optional<int> spinUntilPeerDone(TestBus& bus, Child& peer, double timeout_s);

// A fresh directory under $TMPDIR (or /tmp), removed with its content on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace vslam::transport_test
