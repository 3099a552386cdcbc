# bench_recognition: recognition against 10-10,000 landmarks (synthetic SIFT-like
# and rendered-view SIFT descriptors); figures in docs/frontend.md ("Recognition").
add_executable(bench_recognition ${CMAKE_CURRENT_LIST_DIR}/bench_recognition.cpp)
target_link_libraries(bench_recognition PRIVATE vslam_frontend vslam_world vslam_test_support vslam_bench_main)
target_compile_definitions(bench_recognition PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
