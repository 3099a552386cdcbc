#pragma once
// Where vslam-odometry-bridge's lines come from: stdin, a serial port (or a
// pseudo-terminal) in raw mode, or a UDP socket bound to localhost. Each
// source is read with poll() and a timeout, so the caller can stop between
// reads. No LCM.

#include <cstddef>
#include <string>

namespace vslam::odometry_bridge {

enum class SourceKind { kStdin, kSerial, kUdp };

struct SourceParams {
  SourceKind kind = SourceKind::kStdin;
  std::string serial_device;  // kSerial: e.g. /dev/ttyUSB0 (no default: the robot's)
  int baud = 115200;          // kSerial
  int udp_port = 0;           // kUdp: bound on 127.0.0.1 (no default)
};

// Whether termios has a speed constant for this rate (9600 ... 921600).
bool isSupportedBaud(int baud);

class LineSource {
 public:
  enum class Status {
    kLine,     // *line holds one line, without its newline
    kTimeout,  // nothing complete within the timeout
    kClosed,   // end of input (stdin at EOF, a serial device that went away)
  };

  // Opens the source; throws std::runtime_error saying what failed (the
  // device, the port) and why (errno text).
  explicit LineSource(SourceParams params);
  ~LineSource();
  LineSource(const LineSource&) = delete;
  LineSource& operator=(const LineSource&) = delete;

  // Waits up to timeout_ms for a line. A line longer than max_line is
  // returned cut at max_line + 1 bytes (the rest up to its newline is
  // discarded), so the caller can reject it as too long. A UDP datagram ends
  // a line even without a newline.
  Status next(std::string* line, int timeout_ms, size_t max_line);
  // Closes and opens the device again (a serial adapter unplugged and back);
  // throws as the constructor.
  void reopen();
  const SourceParams& params() const { return params_; }
  std::string describe() const;  // "stdin", "serial /dev/ttyUSB0 at 115200 baud", ...

 private:
  void open();
  void close();
  // Moves one complete line from buffer_ to *line; false if none.
  bool takeLine(std::string* line, size_t max_line);

  SourceParams params_;
  int fd_ = -1;
  std::string buffer_;
  bool discarding_ = false;  // inside an over-long line, until its newline
  bool at_eof_ = false;
};

}  // namespace vslam::odometry_bridge
