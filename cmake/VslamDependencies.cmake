# Every external dependency is found here, from Debian's packages (scripts/setup
# installs them). LCM 1.3.1 has a pkg-config file but no CMake config.
find_package(PkgConfig REQUIRED)
pkg_check_modules(LCM REQUIRED IMPORTED_TARGET lcm)
find_package(yaml-cpp REQUIRED)
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs features2d calib3d)
find_package(Ceres REQUIRED)
find_package(TBB REQUIRED)
find_package(SQLite3 REQUIRED)
find_package(CLI11 CONFIG REQUIRED)  # command lines (header-only)

if(VSLAM_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(VSLAM_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
