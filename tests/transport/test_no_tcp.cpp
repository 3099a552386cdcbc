// What the stack exposes to the network (docs/reliability.md, "Security"):
//  - the default LCM URL, wherever it is written (the struct default in
//    config/stack_config.hpp, any lcm.url of the shipped configs, the
//    scripts' default in scripts/lib/default-lcm-url, scripts/spy's), has ttl=0:
//    its multicast does not leave the host;
//  - real processes (vslam-deadreckon, vslam-landmark-db with a map file) on
//    the default URL, in a private network namespace, hold UDP sockets and no
//    TCP socket at all, so nothing listens on TCP; supervisord, under
//    scripts/launch, is controlled through a Unix socket only.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>
#include <vslam/health_t.hpp>

#include "config/stack_config.hpp"
#include "process_harness.hpp"

namespace fs = std::filesystem;
namespace tt = vslam::transport_test;

namespace {

// The ttl an LCM URL's options set: its value as written, "missing", or
// "repeated" (LCM would take one of them; the test takes none).
std::string ttlOf(const std::string& url) {
  const size_t query = url.find('?');
  std::vector<std::string> values;
  if (query != std::string::npos) {
    std::stringstream options(url.substr(query + 1));
    std::string option;
    while (std::getline(options, option, '&')) {
      if (option.rfind("ttl=", 0) == 0) values.push_back(option.substr(4));
    }
  }
  if (values.empty()) return "missing";
  if (values.size() > 1) return "repeated";
  return values[0];
}

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The udpm:// URLs in a shell script's lines that are not comments.
std::vector<std::string> scriptUrls(const fs::path& script) {
  std::vector<std::string> urls;
  std::stringstream lines(readText(script));
  std::string line;
  const std::regex url(R"(udpm://[^'"}\s]+)");
  while (std::getline(lines, line)) {
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    for (std::sregex_iterator m(line.begin(), line.end(), url), end; m != end; ++m) {
      urls.push_back(m->str());
    }
  }
  return urls;
}

TEST(DefaultUrl, KeepsMulticastOnTheHost) {
  EXPECT_EQ(ttlOf(vslam::config::kDefaultLcmUrl), "0")
      << "config::kDefaultLcmUrl = " << vslam::config::kDefaultLcmUrl;

  // A shipped stack config may set lcm.url; then that is the default.
  int configs = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(VSLAM_SOURCE_DIR) / "config")) {
    if (entry.path().extension() != ".yaml") continue;
    ++configs;
    const auto stack = vslam::config::StackConfig::loadFile(entry.path());
    if (!stack.lcm_url.empty()) {
      EXPECT_EQ(ttlOf(stack.lcm_url), "0") << entry.path() << ": lcm.url " << stack.lcm_url;
    }
  }
  EXPECT_GE(configs, 1) << "no stack config found in " << VSLAM_SOURCE_DIR << "/config";

  // The scripts' default (scripts/launch passes its URL to every program
  // with --lcm-url, over any lcm.url of the config): one file, the same URL
  // as the processes', read by scripts/launch, scripts/record and the
  // campaigns (scripts/lib/live_stack.py); scripts/spy has its own.
  const fs::path scripts = fs::path(VSLAM_SOURCE_DIR) / "scripts";
  std::string shared = readText(scripts / "lib" / "default-lcm-url");
  shared.erase(shared.find_last_not_of(" \n") + 1);
  EXPECT_EQ(shared, vslam::config::kDefaultLcmUrl) << scripts / "lib" / "default-lcm-url";
  for (const char* name : {"launch", "record", "lib/live_stack.py"}) {
    EXPECT_NE(readText(scripts / name).find("default-lcm-url"), std::string::npos)
        << scripts / name << " no longer reads scripts/lib/default-lcm-url: update this test";
    for (const auto& url : scriptUrls(scripts / name)) {
      EXPECT_EQ(ttlOf(url), "0") << scripts / name << ": " << url;
    }
  }
  const auto spy_urls = scriptUrls(scripts / "spy");
  EXPECT_FALSE(spy_urls.empty()) << "scripts/spy names no udpm:// URL outside its comments";
  for (const auto& url : spy_urls) EXPECT_EQ(ttlOf(url), "0") << "scripts/spy: " << url;

  // ttlOf itself.
  EXPECT_EQ(ttlOf("udpm://239.255.76.67:7667?ttl=1"), "1");
  EXPECT_EQ(ttlOf("udpm://239.255.76.67:7667"), "missing");
  EXPECT_EQ(ttlOf("udpm://239.255.76.67:7667?recv_buf_size=1&ttl=0&ttl=1"), "repeated");
}

TEST(DefaultUrl, SupervisordListensOnAUnixSocketOnly) {
  // [inet_http_server] would make supervisord listen on TCP, with its
  // control (start, stop, run) open to the network.
  std::vector<fs::path> files = {fs::path(VSLAM_SOURCE_DIR) / "scripts" / "launch"};
  for (const auto& entry :
       fs::directory_iterator(fs::path(VSLAM_SOURCE_DIR) / "config" / "launch")) {
    files.push_back(entry.path());
  }
  for (const auto& file : files) {
    EXPECT_EQ(readText(file).find("inet_http_server"), std::string::npos) << file;
  }
  EXPECT_NE(readText(files[0]).find("[unix_http_server]"), std::string::npos);
}

// ---- processes on the default URL --------------------------------------------------

// Socket inodes a process holds open (its /proc/PID/fd links "socket:[N]").
std::set<std::string> socketInodes(pid_t pid) {
  std::set<std::string> inodes;
  std::error_code ec;
  for (const auto& fd : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    const std::string target = fs::read_symlink(fd.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0 && target.back() == ']') {
      inodes.insert(target.substr(8, target.size() - 9));
    }
  }
  return inodes;
}

// The sockets of a /proc/net table (tcp, tcp6, udp, udp6) of this network
// namespace: inode -> state (hex; 0A is TCP's LISTEN).
std::map<std::string, std::string> procNetSockets(const std::string& table) {
  std::map<std::string, std::string> sockets;
  std::ifstream in("/proc/net/" + table);
  std::string line;
  std::getline(in, line);  // column titles
  while (std::getline(in, line)) {
    std::stringstream fields(line);
    std::vector<std::string> f;
    std::string field;
    while (fields >> field) f.push_back(field);
    // sl local rem st tx:rx tr:when retrnsmt uid timeout inode ...
    if (f.size() >= 10) sockets[f[9]] = f[3];
  }
  return sockets;
}

class NoTcpNetns : public tt::NetnsTest {};

TEST_F(NoTcpNetns, ProcessesOnTheDefaultUrlHoldNoTcpSocket) {
  VSLAM_IN_FRESH_NETNS();
  // The default: no --lcm-url, no $LCM_DEFAULT_URL, no lcm.url in the config.
  unsetenv("LCM_DEFAULT_URL");
  const std::string url = vslam::config::kDefaultLcmUrl;
  tt::TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  // The shipped config for vslam-deadreckon; the landmark DB's map in the
  // test's directory.
  const std::string shipped = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  const std::string db_config = dir.path() + "/vslam.yaml";
  std::ofstream(db_config)
      << "robot: " << VSLAM_SOURCE_DIR << "/config/robot/sim_two_camera.yaml\n"
      << "processes:\n"
      << "  landmark_db:\n"
      << "    role: landmark_db\n"
      << "    map_file: " << dir.path() << "/landmarks.vslam-map\n"
      << "    allow_new_landmarks: true\n"
      << "    summary_period_s: 1\n"
      << "    flush_period_s: 1\n"
      << "    prune: {enabled: false, period_s: 30, min_age_s: 120, min_recognitions: 3,\n"
      << "            min_verdicts: 10, min_accepted_ratio: 0.3, duplicate_distance_m: 0.3,\n"
      << "            duplicate_angle_deg: 20, duplicate_min_shared: 0.3}\n"
      << "    segmentation: {region_size_m: 4, active_radius_m: 8, memory_budget_mb: 64,\n"
      << "                   reevaluate_distance_m: 1}\n";

  tt::TestBus bus(url);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << url;
  std::set<std::string> healthy;  // instances that reported
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::health_t h;
    if (h.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) {
      healthy.insert(h.instance);
    }
  });

  struct Started {
    std::string instance;
    std::string log;
    tt::Child child;
  };
  std::vector<Started> processes;
  for (const auto& [program, instance, config] :
       std::vector<std::array<std::string, 3>>{{"vslam-deadreckon", "deadreckon", shipped},
                                               {"vslam-landmark-db", "landmark_db", db_config}}) {
    const std::string log = dir.path() + "/" + instance + ".log";
    processes.push_back({instance, log,
                         tt::Child::spawn({std::string(VSLAM_BIN_DIR) + "/" + program, "--config",
                                           config, "--instance", instance},
                                          {}, log)});
    ASSERT_TRUE(processes.back().child.valid()) << program;
  }
  auto allRunning = [&] {
    for (auto& p : processes) {
      if (!p.child.running()) return false;
    }
    return true;
  };
  // A first HEALTH from each: it has opened LCM and subscribed.
  const bool up =
      bus.spinUntil([&] { return healthy.size() == processes.size() || !allRunning(); }, 15.0);
  for (auto& p : processes) {
    ASSERT_TRUE(p.child.running())
        << p.instance << " " << tt::describeStatus(p.child.status().value_or(0))
        << "; its output:\n"
        << readText(p.log);
  }
  ASSERT_TRUE(up) << "no HEALTH from every process within 15 s";

  const auto tcp = procNetSockets("tcp");
  const auto tcp6 = procNetSockets("tcp6");
  auto udp = procNetSockets("udp");
  for (const auto& [inode, state] : procNetSockets("udp6")) udp[inode] = state;
  for (auto& p : processes) {
    SCOPED_TRACE(p.instance);
    // The URL it says it opened (bus/process_main.cpp logs "LCM <url>").
    const std::string log = readText(p.log);
    const size_t at = log.find(", LCM udpm://");
    ASSERT_NE(at, std::string::npos) << "no LCM URL in its start-up line:\n" << log;
    const std::string used = log.substr(at + 6, log.find_first_of(" \n", at + 6) - (at + 6));
    EXPECT_EQ(used, url);
    EXPECT_EQ(ttlOf(used), "0");

    const auto sockets = socketInodes(p.child.pid());
    int udp_sockets = 0;
    for (const auto& inode : sockets) {
      if (udp.count(inode)) ++udp_sockets;
      for (const auto* table : {&tcp, &tcp6}) {
        const auto found = table->find(inode);
        if (found != table->end()) {
          ADD_FAILURE() << "a TCP socket (inode " << inode << ", state " << found->second
                        << (found->second == "0A" ? ", LISTEN" : "") << ")";
        }
      }
    }
    // The scan sees its sockets at all: LCM's UDP ones are there.
    EXPECT_GE(udp_sockets, 1) << "no UDP socket found among " << sockets.size() << " sockets";
  }
  // Nothing in this namespace listens on TCP (it holds only these processes and the test).
  for (const auto* table : {&tcp, &tcp6}) {
    for (const auto& [inode, state] : *table) {
      EXPECT_NE(state, "0A") << "a TCP socket listening in the namespace (inode " << inode << ")";
    }
  }
}

}  // namespace
