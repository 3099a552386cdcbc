# Creation then measurement on rendered frames from known offsets, forward
# and backward camera (the front-end issue's end-to-end geometry test).
vslam_add_gtest(test_rendered_measurement
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_rendered_measurement.cpp
  LIBS vslam_frontend vslam_world
  LABELS unit
  TIMEOUT 120)
target_compile_definitions(test_rendered_measurement PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
