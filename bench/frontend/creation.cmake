# bench_creation: SIFT per frame and three-view landmark creation on rendered
# simulator frames; figures in docs/frontend.md ("Landmark creation").
add_executable(bench_creation ${CMAKE_CURRENT_LIST_DIR}/bench_creation.cpp)
target_link_libraries(bench_creation PRIVATE vslam_frontend vslam_world vslam_bench_main)
target_compile_definitions(bench_creation PRIVATE VSLAM_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
