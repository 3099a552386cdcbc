# Helpers so every library, process and test is declared the same way.

# vslam_add_process(ROLE SOURCES ... LIBS ...) -> executable bin/vslam-<ROLE>
function(vslam_add_process role)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  set(target vslam-${role})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE ${ARG_LIBS})
  install(TARGETS ${target} RUNTIME DESTINATION bin)
endfunction()

# vslam_add_gtest(NAME SOURCES ... LIBS ... [LABELS ...] [TIMEOUT s])
function(vslam_add_gtest name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gtest_main)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  if(VSLAM_SANITIZE)
    # Instrumented code at -Og (scripts/test) runs 1.3-3x slower.
    math(EXPR ARG_TIMEOUT "${ARG_TIMEOUT} * 3")
  endif()
  # CTest starts the costliest tests first. A fresh clone has no measured
  # costs yet, and a minute-long replay test that started last kept the
  # whole suite waiting for it on 2 cores.
  set(cost 1)
  if("replay" IN_LIST ARG_LABELS)
    set(cost 100)
  endif()
  gtest_discover_tests(${name}
    WORKING_DIRECTORY ${CMAKE_SOURCE_DIR}
    PROPERTIES LABELS "${ARG_LABELS}" TIMEOUT ${ARG_TIMEOUT} COST ${cost}
    DISCOVERY_TIMEOUT 60)
endfunction()
