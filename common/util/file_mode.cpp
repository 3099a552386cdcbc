#include "util/file_mode.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace vslam::util {
namespace {

// errno read first: building the message may change it.
std::string failed(const char* call, int error = errno) {
  return std::string(call) + " (to make it owner-only, mode 0600): " + std::strerror(error);
}

}  // namespace

std::optional<std::string> createOwnerOnly(const std::filesystem::path& file) {
  // The mode given to open() passes through the umask, which can only take
  // bits away; fchmod() then sets exactly 0600, on the file opened (no race
  // with a rename of the path in between). Opened read-only, so that an
  // existing file without write permission can be fixed too.
  int fd = -1;
  do {
    fd = ::open(file.c_str(), O_RDONLY | O_CREAT | O_CLOEXEC, kOwnerOnlyMode);
  } while (fd < 0 && errno == EINTR);
  if (fd < 0) return failed("cannot create or open");
  std::optional<std::string> why;
  if (::fchmod(fd, kOwnerOnlyMode) != 0) why = failed("cannot change its mode");
  ::close(fd);
  return why;
}

std::optional<std::string> restrictToOwner(const std::filesystem::path& file) {
  if (::chmod(file.c_str(), kOwnerOnlyMode) != 0) return failed("cannot change its mode");
  return std::nullopt;
}

}  // namespace vslam::util
