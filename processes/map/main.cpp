// vslam-map: inspect, plot, prune and check a landmark map file (see
// common/landmark_db/map_tool.hpp).
#include <string>
#include <vector>

#include "landmark_db/map_tool.hpp"

int main(int argc, char** argv) {
  return vslam::landmark_db::runMapTool(std::vector<std::string>(argv + 1, argv + argc));
}
