#pragma once
// vslam-viewer's command line: feeds the viewer model (viewer_model.hpp) from
// the bus, or from a log with pause and seek, and shows it in a window or
// writes PNG snapshots.

#include <string>
#include <vector>

namespace vslam::viewer {

// Exit statuses: 0; 1 when the log cannot be read or a snapshot not
// written; 2 for a bad command line or config, or no display without
// --snapshot.
int runViewerCli(const std::vector<std::string>& args);

}  // namespace vslam::viewer
