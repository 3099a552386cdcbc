# bench_measurement: one visual measurement (RANSAC PnP + refinement + statistics);
# figures in docs/frontend.md ("Measurement").
add_executable(bench_measurement ${CMAKE_CURRENT_LIST_DIR}/bench_measurement.cpp)
target_link_libraries(bench_measurement PRIVATE vslam_frontend vslam_bench_main)
