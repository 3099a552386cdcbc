# bench_vocabulary: the vocabulary tree's k-means against cv::kmeans (issue 15);
# figures in docs/benchmarks.md.
add_executable(bench_vocabulary ${CMAKE_CURRENT_LIST_DIR}/bench_vocabulary.cpp)
target_link_libraries(bench_vocabulary PRIVATE vslam_frontend vslam_test_support vslam_bench_main)
