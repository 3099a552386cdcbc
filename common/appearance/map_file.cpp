#include "appearance/map_file.hpp"

#include <sqlite3.h>

#include <map>
#include <sstream>

#include "util/file_mode.hpp"
#include "util/sqlite.hpp"

namespace vslam::appearance {
namespace {

constexpr const char* kFormat = "vslam-appearance-map";
constexpr const char* kVersion = "1";

using Db = sqlite::Database<MapFileError>;

using Statement = sqlite::Statement<MapFileError>;

static_assert(sizeof(float) == 4 && sizeof(double) == 8, "blobs are float32 and float64");
std::string joinCameras(const std::vector<std::string>& cameras) {
  std::string s;
  for (size_t i = 0; i < cameras.size(); ++i) s += (i ? "," : "") + cameras[i];
  return s;
}

}  // namespace

void saveMap(const std::filesystem::path& file, const SavedMap& map) {
  for (const auto& c : map.cameras) {
    if (c.empty() || c.find(',') != std::string::npos) {
      throw MapFileError(file.string() + ": camera name '" + c + "' cannot be saved");
    }
  }
  std::filesystem::path tmp = file;
  tmp += ".tmp";
  std::error_code ec;
  std::filesystem::remove(tmp, ec);
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), ec);
  {
    if (auto why = util::createOwnerOnly(tmp)) {
      throw MapFileError(file.string() + ": cannot save: " + *why);
    }
    Db db(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    db.exec(
        "PRAGMA journal_mode=OFF; BEGIN;"
        "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT);"
        "CREATE TABLE states(state_id INTEGER PRIMARY KEY, utime INTEGER, odom_x REAL,"
        " odom_y REAL, odom_theta REAL);"
        "CREATE TABLE histograms(state_id INTEGER, camera INTEGER, bins BLOB,"
        " PRIMARY KEY (state_id, camera));"
        "CREATE TABLE path(seq INTEGER PRIMARY KEY, state_id INTEGER, known INTEGER,"
        " dx REAL, dy REAL, dtheta REAL, relative_translation REAL, relative_rotation REAL,"
        " odometry_translation REAL, odometry_rotation REAL, covariance BLOB);");
    {
      Statement meta(db, "INSERT INTO meta (key, value) VALUES (:key, :value)");
      const std::pair<std::string, std::string> rows[] = {{"format", kFormat},
                                                          {"version", kVersion},
                                                          {"bins", std::to_string(map.bins)},
                                                          {"cameras", joinCameras(map.cameras)}};
      for (const auto& [k, v] : rows) {
        meta.bind(":key", k);
        meta.bind(":value", v);
        meta.run();
      }
    }
    {
      Statement st(db,
                   "INSERT INTO states (state_id, utime, odom_x, odom_y, odom_theta)"
                   " VALUES (:state_id, :utime, :odom_x, :odom_y, :odom_theta)");
      Statement hist(db,
                     "INSERT INTO histograms (state_id, camera, bins)"
                     " VALUES (:state_id, :camera, :bins)");
      for (const auto& s : map.states) {
        st.bind(":state_id", s.id);
        st.bind(":utime", s.utime);
        st.bind(":odom_x", s.odometry.x);
        st.bind(":odom_y", s.odometry.y);
        st.bind(":odom_theta", s.odometry.theta);
        st.run();
        for (size_t c = 0; c < s.histograms.size(); ++c) {
          hist.bind(":state_id", s.id);
          hist.bind(":camera", c);
          hist.bindBlob(":bins", s.histograms[c]);
          hist.run();
        }
      }
    }
    {
      Statement p(db,
                  "INSERT INTO path (seq, state_id, known, dx, dy, dtheta, relative_translation,"
                  " relative_rotation, odometry_translation, odometry_rotation, covariance)"
                  " VALUES (:seq, :state_id, :known, :dx, :dy, :dtheta, :relative_translation,"
                  " :relative_rotation, :odometry_translation, :odometry_rotation, :covariance)");
      for (size_t i = 0; i < map.path.size(); ++i) {
        const auto& v = map.path[i];
        const Link& l = v.link;
        p.bind(":seq", i);
        p.bind(":state_id", v.state_id);
        p.bind(":known", (i > 0 && l.known) ? 1 : 0);
        p.bind(":dx", l.action.x);
        p.bind(":dy", l.action.y);
        p.bind(":dtheta", l.action.theta);
        p.bind(":relative_translation", l.model.relative_translation);
        p.bind(":relative_rotation", l.model.relative_rotation);
        p.bind(":odometry_translation", l.model.odometry_translation);
        p.bind(":odometry_rotation", l.model.odometry_rotation);
        // Symmetric, so row- and column-major are the same nine values.
        p.bindBlob(":covariance",
                   std::vector<double>(l.covariance.data(), l.covariance.data() + 9));
        p.run();
      }
    }
    db.exec("COMMIT;");
  }
  std::filesystem::rename(tmp, file, ec);
  if (ec) throw MapFileError(file.string() + ": cannot replace: " + ec.message());
}

SavedMap loadMap(const std::filesystem::path& file) {
  if (std::error_code ec; !std::filesystem::is_regular_file(file, ec)) {
    throw MapFileError(file.string() + ": no such map file");
  }
  Db db(file, SQLITE_OPEN_READONLY);
  const std::string name = file.string();
  SavedMap m;
  std::map<std::string, std::string> meta;
  try {
    Statement s(db, "SELECT key, value FROM meta");
    while (s.step()) {
      if (!s.isNull(0) && !s.isNull(1)) meta[s.text(0)] = s.text(1);
    }
  } catch (const MapFileError&) {
    throw MapFileError(name + ": not an appearance map (no meta table)");
  }
  if (meta["format"] != kFormat) throw MapFileError(name + ": not an appearance map");
  if (meta["version"] != kVersion) {
    throw MapFileError(name + ": map version '" + meta["version"] + "', expected " + kVersion);
  }
  try {
    m.bins = std::stoi(meta["bins"]);
  } catch (const std::exception&) {
    throw MapFileError(name + ": bad bins '" + meta["bins"] + "'");
  }
  if (m.bins < 1) throw MapFileError(name + ": bad bins " + meta["bins"]);
  {
    std::stringstream ss(meta["cameras"]);
    std::string c;
    while (std::getline(ss, c, ',')) m.cameras.push_back(c);
  }
  if (m.cameras.empty()) throw MapFileError(name + ": no cameras");

  std::map<int64_t, size_t> index;
  {
    Statement s(db,
                "SELECT state_id, utime, odom_x, odom_y, odom_theta FROM states ORDER BY rowid");
    while (s.step()) {
      State st;
      st.id = s.int64(0);
      st.utime = s.int64(1);
      st.odometry = {s.real(2), s.real(3), s.real(4)};
      if (st.id < 0) throw MapFileError(name + ": negative state id");
      st.histograms.assign(m.cameras.size(), Histogram{});
      index[st.id] = m.states.size();
      m.states.push_back(std::move(st));
    }
  }
  {
    Statement s(db, "SELECT state_id, camera, bins FROM histograms");
    while (s.step()) {
      const int64_t id = s.int64(0);
      const int camera = static_cast<int>(s.int64(1));
      const auto it = index.find(id);
      if (it == index.end() || camera < 0 || camera >= static_cast<int>(m.cameras.size())) {
        throw MapFileError(name + ": histogram of unknown state " + std::to_string(id) +
                           " / camera " + std::to_string(camera));
      }
      Histogram h;
      if (!s.blob(2, &h) || (!h.empty() && static_cast<int>(h.size()) != m.bins)) {
        throw MapFileError(name + ": histogram of state " + std::to_string(id) + " does not have " +
                           std::to_string(m.bins) + " bins");
      }
      m.states[it->second].histograms[static_cast<size_t>(camera)] = std::move(h);
    }
  }
  {
    Statement s(db,
                "SELECT state_id, known, dx, dy, dtheta, relative_translation, relative_rotation,"
                " odometry_translation, odometry_rotation, covariance FROM path ORDER BY seq");
    while (s.step()) {
      SavedMap::Visit v;
      v.state_id = s.int64(0);
      if (!index.count(v.state_id)) {
        throw MapFileError(name + ": path visits unknown state " + std::to_string(v.state_id));
      }
      v.link.known = s.int64(1) != 0;
      v.link.action = {s.real(2), s.real(3), s.real(4)};
      v.link.model.relative_translation = s.real(5);
      v.link.model.relative_rotation = s.real(6);
      v.link.model.odometry_translation = s.real(7);
      v.link.model.odometry_rotation = s.real(8);
      std::vector<double> cov;
      if (!s.blob(9, &cov) || cov.size() != 9) {
        throw MapFileError(name + ": path row without a 3x3 covariance");
      }
      for (int i = 0; i < 9; ++i) v.link.covariance.data()[i] = cov[static_cast<size_t>(i)];
      if (!v.link.action.isFinite() || !v.link.covariance.allFinite()) {
        throw MapFileError(name + ": non-finite link in the path");
      }
      m.path.push_back(v);
    }
  }
  return m;
}

}  // namespace vslam::appearance
