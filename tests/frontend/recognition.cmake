vslam_add_gtest(test_landmark_index SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_landmark_index.cpp
  LIBS vslam_frontend vslam_test_support LABELS unit TIMEOUT 60)
