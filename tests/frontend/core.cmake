# The front-end's LCM-free core on rendered frames (no bus, no LCM).
vslam_add_gtest(test_frontend_core SOURCES ${CMAKE_CURRENT_LIST_DIR}/test_frontend_core.cpp
  LIBS vslam_frontend vslam_world LABELS unit TIMEOUT 120)
target_compile_definitions(test_frontend_core PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
