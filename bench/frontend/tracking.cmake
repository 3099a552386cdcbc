# bench_tracking: tracking one camera frame at a 1,000-landmark map (issue 16,
# deliverable 2): SIFT, recognition, measurement and the back-end's update on
# rendered apartment frames, one core; figures in docs/benchmarks.md.
add_executable(bench_tracking ${CMAKE_CURRENT_LIST_DIR}/bench_tracking.cpp)
# vslam_stages for the processes' own parameter loading from config/vslam.yaml
# (no bus is used); vslam_sim for the apartment scenario's path and odometry.
target_link_libraries(bench_tracking PRIVATE vslam_stages vslam_sim vslam_world vslam_bench_main)
target_compile_definitions(bench_tracking PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
