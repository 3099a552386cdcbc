#pragma once
// Files that hold what a robot has seen (the landmark DB's map, the
// appearance map) are readable by their owner only: mode 0600, whatever the
// umask. SQLite gives a database's -journal, -wal and -shm files the mode of
// the database file itself, so a map made owner-only before SQLite first
// opens it keeps its companions owner-only too.

#include <filesystem>
#include <optional>
#include <string>

namespace vslam::util {

inline constexpr unsigned kOwnerOnlyMode = 0600;  // read and write for the owner only

// Creates `file` empty if it does not exist (never truncating one that does)
// and sets its mode to 0600. Why not (the failing call and the system's
// reason, without the file's name: the caller's error names it).
std::optional<std::string> createOwnerOnly(const std::filesystem::path& file);

// Sets the mode of the existing `file` to 0600. Why not, as above (a file
// that does not exist is an error).
std::optional<std::string> restrictToOwner(const std::filesystem::path& file);

}  // namespace vslam::util
