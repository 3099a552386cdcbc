# The visual measurement (paper 4.2) and the pre-filter (paper 5).
vslam_add_gtest(test_pose_measurement
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_pose_measurement.cpp
  LIBS vslam_frontend vslam_lcmtypes
  LABELS unit
  TIMEOUT 120)
