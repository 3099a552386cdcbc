#pragma once
// Synthetic landmarks for the landmark DB tests: random SIFT-like descriptors
// (seeded, so a "same place" landmark can share them) and points.

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "landmark_db/landmark_record.hpp"

namespace vslam::landmark_db::test {

inline LandmarkStructure syntheticStructure(int num_points, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<float> coord(-1.0f, 1.0f);
  LandmarkStructure s;
  s.num_points = num_points;
  s.descriptor_size = 128;
  for (int i = 0; i < num_points; ++i) {
    s.points.insert(s.points.end(), {2.0f + coord(rng), coord(rng), 0.5f + coord(rng)});
    s.keypoints.insert(s.keypoints.end(), {coord(rng), coord(rng)});
    s.scales.push_back(2.0f + coord(rng));
    s.orientations.push_back(coord(rng));
    for (int k = 0; k < 128; ++k) s.descriptors.push_back(static_cast<uint8_t>(byte(rng)));
  }
  return s;
}

inline LandmarkInfo syntheticInfo(const std::string& camera, int64_t proposal_id, Utime t,
                                  const Pose2& odom) {
  LandmarkInfo i;
  i.camera = camera;
  i.proposal_id = proposal_id;
  i.created_utime = t;
  i.created_odom = odom;
  return i;
}

inline std::string fileBytes(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace vslam::landmark_db::test
