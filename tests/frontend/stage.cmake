vslam_add_gtest(test_frontend_stage SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_frontend_stage.cpp
  LIBS vslam_stages vslam_sim vslam_test_support LABELS replay TIMEOUT 300)
target_compile_definitions(test_frontend_stage PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
