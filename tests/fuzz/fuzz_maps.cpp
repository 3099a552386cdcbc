// Map files as they may be found on disk (damaged, truncated, another
// program's SQLite database, not a database at all): the first byte picks
// the reader, the rest is the file. The landmark DB's store and the
// appearance map's loader must refuse a bad file with their MapFileError
// naming it, and read a good one; any other exception, a crash or a
// sanitizer report is a finding.

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "appearance/map_file.hpp"
#include "fuzz_target.hpp"
#include "landmark_db/landmark_store.hpp"

namespace fs = std::filesystem;

namespace {

std::string readBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void readLandmarkMap(const fs::path& file) {
  vslam::landmark_db::StoreOptions options;
  options.create_if_missing = false;
  options.read_only = true;
  try {
    vslam::landmark_db::LandmarkStore store(file, options);
    for (const auto& info : store.loadAllInfo()) (void)store.loadStructure(info.id);
  } catch (const vslam::landmark_db::MapFileError& e) {
    if (std::string(e.what()).empty()) std::abort();
  }
}

void readAppearanceMap(const fs::path& file) {
  try {
    (void)vslam::appearance::loadMap(file);
  } catch (const vslam::appearance::MapFileError& e) {
    if (std::string(e.what()).empty()) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const fs::path file = vslam::fuzz::scratchDir("maps") / "map";
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(file.string() + suffix);
  std::ofstream(file, std::ios::binary)
      .write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  if (data[0] % 2 == 0) {
    readLandmarkMap(file);
  } else {
    readAppearanceMap(file);
  }
  return 0;
}

std::vector<std::string> vslam::fuzz::seeds() {
  const fs::path dir = vslam::fuzz::scratchDir("maps");
  std::vector<std::string> out;
  {  // a landmark map with two landmarks
    const fs::path file = dir / "seed.vslam-map";
    fs::remove(file);
    {
      vslam::landmark_db::StoreOptions options;
      options.new_database_id = "fuzz-seed";
      options.power_safe = false;
      vslam::landmark_db::LandmarkStore store(file, options);
      for (int n = 1; n <= 2; ++n) {
        vslam::landmark_db::LandmarkStructure s;
        s.num_points = 2;
        s.points = {0.1f, 0.2f, 1.0f, -0.1f, 0.3f, 1.5f};
        s.keypoints = {0.1f, 0.2f, -0.1f, 0.05f};
        s.scales = {2.0f, 3.0f};
        s.orientations = {0.5f, 1.0f};
        s.descriptors.assign(2 * 128, static_cast<uint8_t>(n * 10));
        vslam::landmark_db::LandmarkInfo info;
        info.camera = "forward";
        info.proposal_id = n;
        info.fingerprint = s.fingerprint();
        info.num_points = 2;
        store.insert(info, s, n);
      }
    }
    // The WAL is checkpointed into the file when the store closes.
    out.push_back(std::string(1, '\0') + readBytes(file));
  }
  {  // an appearance map of two states
    vslam::appearance::SavedMap map;
    map.cameras = {"forward"};
    map.bins = 4;
    for (int id = 0; id < 2; ++id) {
      vslam::appearance::State state;
      state.id = id;
      state.utime = 1000000 * id;
      state.histograms = {{0.25f, 0.25f, 0.25f, 0.25f}};
      map.states.push_back(state);
      vslam::appearance::SavedMap::Visit visit;
      visit.state_id = id;
      map.path.push_back(visit);
    }
    const fs::path file = dir / "seed.appearance-map";
    vslam::appearance::saveMap(file, map);
    out.push_back(std::string(1, '\1') + readBytes(file));
  }
  return out;
}
