#include "landmark_db/landmark_store.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "util/file_mode.hpp"
#include "util/sqlite.hpp"

namespace vslam::landmark_db {
namespace {

constexpr const char* kFormat = "vslam-landmark-map";
constexpr const char* kRobotPoseKey = "robot_pose";

std::string formatRobotPose(const RobotPoseRecord& r) {
  std::ostringstream out;
  out.precision(17);
  out << r.utime << ' ' << r.map_pose.x << ' ' << r.map_pose.y << ' ' << r.map_pose.theta << ' '
      << r.odom_pose.x << ' ' << r.odom_pose.y << ' ' << r.odom_pose.theta;
  for (double c : r.covariance) out << ' ' << c;
  return out.str();
}

// nullopt unless all 16 numbers are there and finite.
std::optional<RobotPoseRecord> parseRobotPose(const std::string& text) {
  std::istringstream in(text);
  RobotPoseRecord r;
  in >> r.utime >> r.map_pose.x >> r.map_pose.y >> r.map_pose.theta >> r.odom_pose.x >>
      r.odom_pose.y >> r.odom_pose.theta;
  for (double& c : r.covariance) in >> c;
  std::string rest;
  if (in.fail() || (in >> rest) || !r.map_pose.isFinite() || !r.odom_pose.isFinite()) {
    return std::nullopt;
  }
  for (double c : r.covariance) {
    if (!std::isfinite(c)) return std::nullopt;
  }
  return r;
}

static_assert(sizeof(float) == 4, "blobs are float32");

using Database = sqlite::Database<MapFileError>;
using Statement = sqlite::Statement<MapFileError>;

constexpr const char* kInfoColumns =
    "landmark_id, camera, proposal_id, version, revision, created_utime, odom_x, odom_y,"
    " odom_theta, num_points, num_recognitions, num_accepted, num_rejected, last_seen_utime,"
    " pose_source, map_x, map_y, map_theta, fingerprint";

LandmarkInfo readInfo(Statement& s) {
  LandmarkInfo i;
  i.id = s.int64(0);
  i.camera = s.text(1);
  i.proposal_id = s.int64(2);
  i.version = static_cast<int32_t>(s.int64(3));
  i.revision = s.int64(4);
  i.created_utime = s.int64(5);
  i.created_odom = {s.real(6), s.real(7), s.real(8)};
  i.num_points = static_cast<int32_t>(s.int64(9));
  i.stats.num_recognitions = static_cast<int32_t>(s.int64(10));
  i.stats.num_accepted = static_cast<int32_t>(s.int64(11));
  i.stats.num_rejected = static_cast<int32_t>(s.int64(12));
  i.stats.last_seen_utime = s.int64(13);
  const int64_t src = s.int64(14);
  i.pose_source = src == 2   ? PoseSource::kMap
                  : src == 1 ? PoseSource::kProvisional
                             : PoseSource::kOdometry;
  i.map_pose = {s.real(15), s.real(16), s.real(17)};
  i.fingerprint = static_cast<uint64_t>(s.int64(18));
  return i;
}

bool fileExists(const std::string& f) {
  std::error_code ec;
  return std::filesystem::exists(f, ec);
}

}  // namespace

LandmarkStore::LandmarkStore(const std::filesystem::path& file, const StoreOptions& options)
    : file_(file.string()), read_only_(options.read_only) {
  in_memory_ = file_.empty() || file_ == ":memory:";
  if (in_memory_) {
    file_ = ":memory:";
    db_ = std::make_unique<Database>(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    read_only_ = false;
    createSchema(options);
    readMeta();
    return;
  }
  if (!fileExists(file_)) {
    if (!options.create_if_missing || options.read_only) {
      throw MapFileError(file_ + ": no such map file");
    }
    // Built under a temporary name and renamed: a crash never leaves half a schema.
    std::filesystem::path tmp = file;
    tmp += ".new";
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), ec);
    // Owner-only before SQLite opens it: its journal takes the same mode.
    if (auto why = util::createOwnerOnly(tmp))
      throw MapFileError(file_ + ": cannot create: " + *why);
    db_ = std::make_unique<Database>(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE,
                                     "cannot create");
    createSchema(options);
    db_->exec("PRAGMA journal_mode=DELETE");
    db_.reset();
    std::filesystem::rename(tmp, file_, ec);
    if (ec) throw MapFileError(file_ + ": cannot create: " + ec.message());
  }
  // An existing file: check what it is before SQLite may write anything.
  {
    std::ifstream in(file_, std::ios::binary);
    if (!in) throw MapFileError(file_ + ": cannot be read");
    char header[16] = {};
    in.read(header, sizeof(header));
    if (in.gcount() == 0) {
      throw MapFileError(file_ + ": empty file, not a landmark map (left untouched)");
    }
    if (in.gcount() < 16 || std::memcmp(header, "SQLite format 3", 16) != 0) {
      throw MapFileError(file_ +
                         ": not an SQLite database, so not a landmark map (left untouched)");
    }
  }
  // SQLite creates the -wal and -shm files of a WAL-mode map as it opens it;
  // an open that fails removes the ones it created, so a refused file is
  // left as it was found.
  std::vector<std::string> new_sidecars;
  for (const char* suffix : {"-wal", "-shm"}) {
    if (!fileExists(file_ + suffix)) new_sidecars.push_back(file_ + suffix);
  }
  auto closeAndClean = [&] {
    db_.reset();
    std::error_code ec;
    for (const std::string& f : new_sidecars) std::filesystem::remove(f, ec);
  };
  const int flags = read_only_ ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  try {
    db_ = std::make_unique<Database>(file_, flags, "cannot open");
    checkIdentity();
    if (options.quick_check) {
      Statement s(*db_, "PRAGMA quick_check");
      std::string problems;
      while (s.step()) {
        const std::string line = s.text(0);
        if (line != "ok") problems += (problems.empty() ? "" : "; ") + line;
      }
      if (!problems.empty()) {
        throw MapFileError(file_ + ": the map file is damaged (" + problems +
                           "); left untouched: restore a copy or check it with vslam-map check");
      }
    }
    if (!read_only_) {
      db_->exec("PRAGMA journal_mode=WAL");
      db_->exec(options.power_safe ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL");
      if (options.max_file_bytes > 0) {
        Statement ps(*db_, "PRAGMA page_size");
        const int64_t page = ps.step() ? ps.int64(0) : 4096;
        db_->exec("PRAGMA max_page_count=" +
                  std::to_string(std::max<int64_t>(1, static_cast<int64_t>(options.max_file_bytes) /
                                                          std::max<int64_t>(page, 512))));
      }
    }
    readMeta();
  } catch (const MapFileError&) {
    closeAndClean();
    throw;
  } catch (const std::exception& e) {
    closeAndClean();
    throw MapFileError(file_ + ": " + e.what());
  }
}

LandmarkStore::~LandmarkStore() {
  // Fold the WAL into the main file and leave WAL mode, so the map is one
  // file again and a read-only look at it (vslam-map list) creates no
  // -wal/-shm beside it.
  if (db_ && !read_only_ && !in_memory_) {
    db_->tryExec("PRAGMA wal_checkpoint(TRUNCATE)");
    db_->tryExec("PRAGMA journal_mode=DELETE");
  }
}

void LandmarkStore::checkIdentity() {
  int64_t app_id = 0, user_version = 0;
  try {
    Statement s(*db_, "PRAGMA application_id");
    if (!s.step()) throw MapFileError(file_ + ": no application_id");
    app_id = s.int64(0);
  } catch (const MapFileError&) {
    throw MapFileError(file_ + ": not a readable SQLite database (" + db_->lastError() +
                       "); left untouched");
  }
  if (app_id != kApplicationId) {
    std::ostringstream os;
    os << file_ << ": not a vslam landmark map (SQLite application_id 0x" << std::hex << app_id
       << ", expected 0x" << kApplicationId << "); left untouched";
    throw MapFileError(os.str());
  }
  {
    Statement s(*db_, "PRAGMA user_version");
    if (s.step()) user_version = s.int64(0);
  }
  if (user_version != kSchemaVersion) {
    throw MapFileError(file_ + ": landmark map schema " + std::to_string(user_version) +
                       ", this program reads schema " + std::to_string(kSchemaVersion) +
                       "; left untouched");
  }
}

void LandmarkStore::createSchema(const StoreOptions& options) {
  db_->exec("PRAGMA application_id=" + std::to_string(kApplicationId) +
            "; PRAGMA user_version=" + std::to_string(kSchemaVersion) + ";");
  db_->exec(
      "BEGIN;"
      "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);"
      "CREATE TABLE landmarks(landmark_id INTEGER PRIMARY KEY, camera TEXT NOT NULL,"
      " proposal_id INTEGER NOT NULL, version INTEGER NOT NULL, revision INTEGER NOT NULL,"
      " created_utime INTEGER NOT NULL, odom_x REAL, odom_y REAL, odom_theta REAL,"
      " num_points INTEGER NOT NULL, descriptor_size INTEGER NOT NULL, points BLOB NOT NULL,"
      " keypoints BLOB NOT NULL, scales BLOB NOT NULL, orientations BLOB NOT NULL,"
      " descriptors BLOB NOT NULL, num_recognitions INTEGER NOT NULL DEFAULT 0,"
      " num_accepted INTEGER NOT NULL DEFAULT 0, num_rejected INTEGER NOT NULL DEFAULT 0,"
      " last_seen_utime INTEGER NOT NULL DEFAULT 0, pose_source INTEGER NOT NULL DEFAULT 0,"
      " map_x REAL, map_y REAL, map_theta REAL, fingerprint INTEGER NOT NULL,"
      " UNIQUE(camera, proposal_id, fingerprint));");
  {
    Statement s(*db_, "INSERT INTO meta (key, value) VALUES (:key, :value)");
    const std::pair<std::string, std::string> rows[] = {
        {"format", kFormat},
        {"schema", std::to_string(kSchemaVersion)},
        {"database_id", options.new_database_id.empty() ? "unnamed" : options.new_database_id},
        {"revision", "0"},
        {"next_id", "1"},
        {"created_utime", std::to_string(options.now)}};
    for (const auto& [k, v] : rows) {
      s.bind(":key", k);
      s.bind(":value", v);
      s.run();
    }
  }
  db_->exec("COMMIT;");
}

void LandmarkStore::readMeta() {
  std::map<std::string, std::string> meta;
  try {
    Statement s(*db_, "SELECT key, value FROM meta");
    while (s.step()) meta[s.text(0)] = s.text(1);
  } catch (const MapFileError& e) {
    throw MapFileError(file_ + ": a landmark map without its meta table (" + e.what() + ")");
  }
  if (meta["format"] != kFormat) {
    throw MapFileError(file_ + ": meta.format is '" + meta["format"] + "', not '" + kFormat + "'");
  }
  try {
    database_id_ = meta.at("database_id");
    revision_ = std::stoll(meta.at("revision"));
    next_id_ = std::stoll(meta.at("next_id"));
    created_utime_ = std::stoll(meta.at("created_utime"));
  } catch (const std::exception&) {
    throw MapFileError(file_ + ": meta table incomplete or not numeric");
  }
  const auto pose = meta.find(kRobotPoseKey);
  robot_pose_ = pose == meta.end() ? std::nullopt : parseRobotPose(pose->second);
  // next_id never falls below what the table holds (belt and braces).
  Statement s(*db_, "SELECT COALESCE(MAX(landmark_id), 0) FROM landmarks");
  if (s.step()) next_id_ = std::max(next_id_, s.int64(0) + 1);
}

void LandmarkStore::writeMetaValue(const char* key, const std::string& value) {
  Statement s(*db_, "UPDATE meta SET value = :value WHERE key = :key");
  s.bind(":value", value);
  s.bind(":key", std::string(key));
  s.run();
}

void LandmarkStore::saveRobotPose(const std::optional<RobotPoseRecord>& pose) {
  if (read_only_) throw MapFileError(file_ + ": opened read-only");
  if (pose) {
    Statement s(*db_, "INSERT OR REPLACE INTO meta (key, value) VALUES (:key, :value)");
    s.bind(":key", std::string(kRobotPoseKey));
    s.bind(":value", formatRobotPose(*pose));
    s.run();
  } else {
    Statement s(*db_, "DELETE FROM meta WHERE key = :key");
    s.bind(":key", std::string(kRobotPoseKey));
    s.run();
  }
  robot_pose_ = pose;
}

void LandmarkStore::writeTransaction(int64_t revision, const std::function<void()>& body) {
  if (read_only_) throw MapFileError(file_ + ": opened read-only");
  const Utime started = monotonicUtime();
  db_->exec("BEGIN IMMEDIATE");
  try {
    body();
    writeMetaValue("revision", std::to_string(revision));
    db_->exec("COMMIT");
  } catch (...) {
    db_->tryExec("ROLLBACK");
    throw;
  }
  revision_ = revision;
  commit_ms_sum_ += 1e-3 * static_cast<double>(monotonicUtime() - started);
  ++commit_count_;
}

double LandmarkStore::takeMeanCommitMs(int64_t* count) {
  const double mean = commit_count_ > 0 ? commit_ms_sum_ / static_cast<double>(commit_count_) : 0;
  if (count != nullptr) *count = commit_count_;
  commit_ms_sum_ = 0;
  commit_count_ = 0;
  return mean;
}

std::vector<LandmarkInfo> LandmarkStore::loadAllInfo() {
  std::vector<LandmarkInfo> out;
  const std::string sql =
      std::string("SELECT ") + kInfoColumns + " FROM landmarks ORDER BY landmark_id";
  Statement s(*db_, sql.c_str());
  while (s.step()) out.push_back(readInfo(s));
  return out;
}

std::optional<LandmarkStructure> LandmarkStore::loadStructure(int64_t id) {
  Statement s(*db_,
              "SELECT num_points, descriptor_size, points, keypoints, scales, orientations,"
              " descriptors FROM landmarks WHERE landmark_id = :id");
  s.bind(":id", id);
  if (!s.step()) return std::nullopt;
  LandmarkStructure st;
  st.num_points = static_cast<int32_t>(s.int64(0));
  st.descriptor_size = static_cast<int32_t>(s.int64(1));
  const size_t n = st.num_points > 0 ? static_cast<size_t>(st.num_points) : 0;
  const size_t d = st.descriptor_size > 0 ? static_cast<size_t>(st.descriptor_size) : 0;
  if (!s.blob(2, 3 * n, &st.points) || !s.blob(3, 2 * n, &st.keypoints) ||
      !s.blob(4, n, &st.scales) || !s.blob(5, n, &st.orientations) ||
      !s.blob(6, n * d, &st.descriptors)) {
    throw MapFileError(file_ + ": landmark " + std::to_string(id) +
                       ": blob sizes disagree with num_points");
  }
  return st;
}

std::optional<int64_t> LandmarkStore::findProposal(const std::string& camera, int64_t proposal_id,
                                                   uint64_t fingerprint) {
  Statement s(*db_,
              "SELECT landmark_id FROM landmarks WHERE camera = :camera AND"
              " proposal_id = :proposal_id AND fingerprint = :fingerprint");
  s.bind(":camera", camera);
  s.bind(":proposal_id", proposal_id);
  s.bind(":fingerprint", static_cast<int64_t>(fingerprint));
  if (!s.step()) return std::nullopt;
  return s.int64(0);
}

int64_t LandmarkStore::insert(LandmarkInfo info, const LandmarkStructure& st, int64_t revision) {
  if (info.id <= 0) info.id = next_id_;
  const int64_t next_id = std::max(next_id_, info.id + 1);
  writeTransaction(revision, [&] {
    Statement s(*db_,
                "INSERT INTO landmarks (landmark_id, camera, proposal_id, version, revision,"
                " created_utime, odom_x, odom_y, odom_theta, num_points, descriptor_size, points,"
                " keypoints, scales, orientations, descriptors, num_recognitions, num_accepted,"
                " num_rejected, last_seen_utime, pose_source, map_x, map_y, map_theta, fingerprint)"
                " VALUES (:landmark_id, :camera, :proposal_id, :version, :revision,"
                " :created_utime, :odom_x, :odom_y, :odom_theta, :num_points, :descriptor_size,"
                " :points, :keypoints, :scales, :orientations, :descriptors, :num_recognitions,"
                " :num_accepted, :num_rejected, :last_seen_utime, :pose_source, :map_x, :map_y,"
                " :map_theta, :fingerprint)");
    s.bind(":landmark_id", info.id);
    s.bind(":camera", info.camera);
    s.bind(":proposal_id", info.proposal_id);
    s.bind(":version", info.version);
    s.bind(":revision", revision);
    s.bind(":created_utime", info.created_utime);
    s.bind(":odom_x", info.created_odom.x);
    s.bind(":odom_y", info.created_odom.y);
    s.bind(":odom_theta", info.created_odom.theta);
    s.bind(":num_points", st.num_points);
    s.bind(":descriptor_size", st.descriptor_size);
    s.bindBlob(":points", st.points);
    s.bindBlob(":keypoints", st.keypoints);
    s.bindBlob(":scales", st.scales);
    s.bindBlob(":orientations", st.orientations);
    s.bindBlob(":descriptors", st.descriptors);
    s.bind(":num_recognitions", info.stats.num_recognitions);
    s.bind(":num_accepted", info.stats.num_accepted);
    s.bind(":num_rejected", info.stats.num_rejected);
    s.bind(":last_seen_utime", info.stats.last_seen_utime);
    s.bind(":pose_source", static_cast<int64_t>(info.pose_source));
    s.bind(":map_x", info.map_pose.x);
    s.bind(":map_y", info.map_pose.y);
    s.bind(":map_theta", info.map_pose.theta);
    s.bind(":fingerprint", static_cast<int64_t>(info.fingerprint));
    s.run();
    writeMetaValue("next_id", std::to_string(next_id));
  });
  next_id_ = next_id;
  return info.id;
}

void LandmarkStore::updateInfos(const std::vector<LandmarkInfo>& infos, int64_t revision) {
  writeTransaction(revision, [&] {
    Statement s(*db_,
                "UPDATE landmarks SET version = :version, revision = :revision,"
                " num_recognitions = :num_recognitions, num_accepted = :num_accepted,"
                " num_rejected = :num_rejected, last_seen_utime = :last_seen_utime,"
                " pose_source = :pose_source, map_x = :map_x, map_y = :map_y,"
                " map_theta = :map_theta WHERE landmark_id = :landmark_id");
    for (const auto& i : infos) {
      s.bind(":version", i.version);
      s.bind(":revision", i.revision);
      s.bind(":num_recognitions", i.stats.num_recognitions);
      s.bind(":num_accepted", i.stats.num_accepted);
      s.bind(":num_rejected", i.stats.num_rejected);
      s.bind(":last_seen_utime", i.stats.last_seen_utime);
      s.bind(":pose_source", static_cast<int64_t>(i.pose_source));
      s.bind(":map_x", i.map_pose.x);
      s.bind(":map_y", i.map_pose.y);
      s.bind(":map_theta", i.map_pose.theta);
      s.bind(":landmark_id", i.id);
      s.run();
    }
  });
}

void LandmarkStore::updatePoints(int64_t id, const std::vector<float>& points, int32_t version,
                                 int64_t revision) {
  writeTransaction(revision, [&] {
    Statement s(*db_,
                "UPDATE landmarks SET points = :points, version = :version, revision = :revision"
                " WHERE landmark_id = :landmark_id");
    s.bindBlob(":points", points);
    s.bind(":version", version);
    s.bind(":revision", revision);
    s.bind(":landmark_id", id);
    s.run();
  });
}

void LandmarkStore::remove(const std::vector<int64_t>& ids, int64_t revision) {
  writeTransaction(revision, [&] {
    Statement s(*db_, "DELETE FROM landmarks WHERE landmark_id = :landmark_id");
    for (int64_t id : ids) {
      s.bind(":landmark_id", id);
      s.run();
    }
  });
}

void LandmarkStore::setRevision(int64_t revision) {
  writeTransaction(revision, [] {});
}

std::string LandmarkStore::integrityCheck() {
  Statement s(*db_, "PRAGMA integrity_check");
  std::string out;
  while (s.step()) out += (out.empty() ? "" : "\n") + s.text(0);
  return out;
}

int64_t LandmarkStore::fileBytes() const {
  if (in_memory_) return 0;
  int64_t total = 0;
  for (const char* suffix : {"", "-wal"}) {
    std::error_code ec;
    const auto n = std::filesystem::file_size(file_ + suffix, ec);
    if (!ec) total += static_cast<int64_t>(n);
  }
  return total;
}

}  // namespace vslam::landmark_db
