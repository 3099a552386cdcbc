#include "odometry_bridge/line_source.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace vslam::odometry_bridge {
namespace {

speed_t baudConstant(int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 921600:
      return B921600;
    default:
      return B0;
  }
}

std::runtime_error systemError(const std::string& what) {
  return std::runtime_error(what + ": " + std::strerror(errno));
}

}  // namespace

bool isSupportedBaud(int baud) { return baudConstant(baud) != B0; }

LineSource::LineSource(SourceParams params) : params_(std::move(params)) { open(); }

LineSource::~LineSource() { close(); }

std::string LineSource::describe() const {
  switch (params_.kind) {
    case SourceKind::kStdin:
      return "stdin";
    case SourceKind::kSerial:
      return "serial " + params_.serial_device + " at " + std::to_string(params_.baud) + " baud";
    case SourceKind::kUdp:
      return "UDP 127.0.0.1:" + std::to_string(params_.udp_port);
  }
  return "?";
}

void LineSource::open() {
  buffer_.clear();
  discarding_ = false;
  at_eof_ = false;
  switch (params_.kind) {
    case SourceKind::kStdin:
      fd_ = STDIN_FILENO;
      return;
    case SourceKind::kSerial: {
      if (!isSupportedBaud(params_.baud)) {
        throw std::runtime_error("unsupported baud rate " + std::to_string(params_.baud));
      }
      const int fd = ::open(params_.serial_device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
      if (fd < 0) throw systemError("cannot open " + params_.serial_device);
      termios tio{};
      if (tcgetattr(fd, &tio) != 0) {
        const auto e = systemError(params_.serial_device + " is not a serial device");
        ::close(fd);
        throw e;
      }
      // Raw: no echo, no line editing, no translation of CR/NL, 8N1; the
      // bridge does its own line splitting.
      cfmakeraw(&tio);
      tio.c_cflag |= CLOCAL | CREAD;
      tio.c_cc[VMIN] = 0;
      tio.c_cc[VTIME] = 0;
      cfsetispeed(&tio, baudConstant(params_.baud));
      cfsetospeed(&tio, baudConstant(params_.baud));
      if (tcsetattr(fd, TCSANOW, &tio) != 0) {
        const auto e = systemError("cannot configure " + params_.serial_device);
        ::close(fd);
        throw e;
      }
      fd_ = fd;
      return;
    }
    case SourceKind::kUdp: {
      if (params_.udp_port < 1 || params_.udp_port > 65535) {
        throw std::runtime_error("UDP port " + std::to_string(params_.udp_port) +
                                 " is not in 1..65535");
      }
      const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
      if (fd < 0) throw systemError("cannot create a UDP socket");
      sockaddr_in addr{};
      addr.sin_family = AF_INET;
      addr.sin_port = htons(static_cast<uint16_t>(params_.udp_port));
      addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);  // localhost only: nothing from the network
      if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
        const auto e = systemError("cannot bind UDP 127.0.0.1:" + std::to_string(params_.udp_port));
        ::close(fd);
        throw e;
      }
      fd_ = fd;
      return;
    }
  }
}

void LineSource::close() {
  if (fd_ >= 0 && fd_ != STDIN_FILENO) ::close(fd_);
  fd_ = -1;
}

void LineSource::reopen() {
  close();
  open();
}

bool LineSource::takeLine(std::string* line, size_t max_line) {
  while (true) {
    const size_t nl = buffer_.find('\n');
    if (nl == std::string::npos) {
      if (!discarding_ && buffer_.size() > max_line) {
        // Over-long: hand out its start now, drop the rest up to the newline.
        *line = buffer_.substr(0, max_line + 1);
        buffer_.clear();
        discarding_ = true;
        return true;
      }
      if (discarding_) buffer_.clear();
      return false;
    }
    if (discarding_) {
      buffer_.erase(0, nl + 1);
      discarding_ = false;
      continue;
    }
    *line = buffer_.substr(0, std::min(nl, max_line + 1));
    buffer_.erase(0, nl + 1);
    return true;
  }
}

LineSource::Status LineSource::next(std::string* line, int timeout_ms, size_t max_line) {
  if (takeLine(line, max_line)) return Status::kLine;
  if (at_eof_ || fd_ < 0) {
    // The last line of a stream may lack its newline.
    if (!buffer_.empty() && !discarding_) {
      *line = buffer_.substr(0, max_line + 1);
      buffer_.clear();
      return Status::kLine;
    }
    return Status::kClosed;
  }
  pollfd p{fd_, POLLIN, 0};
  const int ready = poll(&p, 1, timeout_ms);
  if (ready < 0) {
    if (errno == EINTR) return Status::kTimeout;
    throw systemError("poll on " + describe());
  }
  if (ready == 0) return Status::kTimeout;
  char chunk[4096];
  if (params_.kind == SourceKind::kUdp) {
    const ssize_t n = recv(fd_, chunk, sizeof(chunk), 0);
    if (n < 0) return errno == EINTR || errno == EAGAIN ? Status::kTimeout : Status::kClosed;
    buffer_.append(chunk, static_cast<size_t>(n));
    if (buffer_.empty() || buffer_.back() != '\n') buffer_.push_back('\n');
  } else {
    const ssize_t n = read(fd_, chunk, sizeof(chunk));
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) return Status::kTimeout;
    if (n <= 0) {
      // EOF, or EIO from a serial device that went away / a pty whose master closed.
      at_eof_ = true;
      return next(line, 0, max_line);
    }
    buffer_.append(chunk, static_cast<size_t>(n));
  }
  return takeLine(line, max_line) ? Status::kLine : Status::kTimeout;
}

}  // namespace vslam::odometry_bridge
