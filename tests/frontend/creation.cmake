# Landmark creation (paper 4.1): features, matching, two-view geometry,
# three-view bundle adjustment, and creation on rendered simulator views.
vslam_add_gtest(test_landmark_creation
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_landmark_creation.cpp
  LIBS vslam_frontend vslam_world
  LABELS unit
  TIMEOUT 120)
target_compile_definitions(test_landmark_creation PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
