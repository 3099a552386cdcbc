#pragma once
// Every file the evaluation tools write goes through here: its folder is
// created when missing (`--write-tum out/run/x.tum` on a fresh checkout), so
// one missing folder does not fail the run after the work is done. If the
// folder cannot be made, the writer's open fails and its error names the file.

#include <filesystem>
#include <system_error>

namespace vslam::eval {

inline void createParentFolder(const std::filesystem::path& file) {
  std::error_code ec;
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), ec);
}

}  // namespace vslam::eval
