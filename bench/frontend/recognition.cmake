add_executable(bench_recognition ${CMAKE_CURRENT_LIST_DIR}/bench_recognition.cpp)
target_link_libraries(bench_recognition PRIVATE vslam_frontend vslam_util benchmark::benchmark)
