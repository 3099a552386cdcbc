# Build-time code generation for LCM types.
#
# Debian's LCM 1.3.1 ships no CMake helper (no lcm_wrap_types), so this file
# runs lcm-gen itself: C++ headers into the build tree (never the source tree)
# behind an INTERFACE target, and a Java jar of the same types for lcm-spy,
# with hand-written Java (JAVA_SOURCES: lcm-spy plugins, which lcm-spy loads
# from its classpath) compiled into the same jar.
# Beside the types it generates <TARGET>/wire_check.hpp (cmake/lcm_wire_check.py):
# a check of an encoded message's counts against its bytes, run before the
# generated decoder, which allocates whatever count a message claims.
#
#   vslam_lcm_types(TARGET name JAR_TARGET name FILES a.lcm b.lcm ... [JAVA_SOURCES x.java ...])

find_program(LCM_GEN_EXECUTABLE lcm-gen REQUIRED)
# The system interpreter (scripts/setup installs it; the scripts run it), not
# whatever python3 a shell's PATH (pyenv, a venv) puts first. The generator
# needs only the standard library.
find_program(VSLAM_PYTHON3 NAMES python3 PATHS /usr/bin NO_DEFAULT_PATH REQUIRED)
set(VSLAM_LCM_WIRE_CHECK_SCRIPT ${CMAKE_CURRENT_LIST_DIR}/lcm_wire_check.py)
find_package(Java 11 COMPONENTS Development REQUIRED)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java REQUIRED)

function(vslam_lcm_types)
  cmake_parse_arguments(ARG "" "TARGET;JAR_TARGET" "FILES;JAVA_SOURCES" ${ARGN})
  set(cpp_root ${CMAKE_CURRENT_BINARY_DIR}/lcmtypes/cpp)
  set(java_root ${CMAKE_CURRENT_BINARY_DIR}/lcmtypes/java)
  set(class_root ${CMAKE_CURRENT_BINARY_DIR}/lcmtypes/classes)

  set(headers)
  set(java_sources)
  foreach(lcm_file ${ARG_FILES})
    get_filename_component(abs ${lcm_file} ABSOLUTE)
    # Files are named <package>_<type>.lcm (libbot2 convention).
    get_filename_component(stem ${abs} NAME_WE)
    string(REGEX MATCH "^([a-z0-9]+)_(.+)$" _ ${stem})
    if(NOT CMAKE_MATCH_1 OR NOT CMAKE_MATCH_2)
      message(FATAL_ERROR "LCM type file ${lcm_file} is not named <package>_<type>.lcm")
    endif()
    set(pkg ${CMAKE_MATCH_1})
    set(type ${CMAKE_MATCH_2})
    set(hpp ${cpp_root}/${pkg}/${type}.hpp)
    set(java ${java_root}/${pkg}/${type}.java)
    add_custom_command(
      OUTPUT ${hpp} ${java}
      COMMAND ${LCM_GEN_EXECUTABLE} --cpp --cpp-std c++11 --cpp-hpath ${cpp_root} ${abs}
      COMMAND ${LCM_GEN_EXECUTABLE} --java --jpath ${java_root} ${abs}
      DEPENDS ${abs}
      COMMENT "lcm-gen ${pkg}.${type}"
      VERBATIM)
    list(APPEND headers ${hpp})
    list(APPEND java_sources ${java})
  endforeach()

  # One header for all the types: vslam::wire::check<Msg>().
  set(wire_check ${cpp_root}/${ARG_TARGET}/wire_check.hpp)
  add_custom_command(
    OUTPUT ${wire_check}
    COMMAND ${VSLAM_PYTHON3} ${VSLAM_LCM_WIRE_CHECK_SCRIPT} --output ${wire_check}
            --namespace vslam::wire ${ARG_FILES}
    DEPENDS ${VSLAM_LCM_WIRE_CHECK_SCRIPT} ${ARG_FILES}
    COMMENT "lcm_wire_check.py ${ARG_TARGET}/wire_check.hpp"
    VERBATIM)
  list(APPEND headers ${wire_check})

  add_custom_target(${ARG_TARGET}_generate DEPENDS ${headers})
  add_library(${ARG_TARGET} INTERFACE)
  add_dependencies(${ARG_TARGET} ${ARG_TARGET}_generate)
  target_include_directories(${ARG_TARGET} SYSTEM INTERFACE ${cpp_root})

  # Java: compile every generated class, and the plugins that use them, into
  # one jar for lcm-spy.
  set(jar ${CMAKE_BINARY_DIR}/share/java/${ARG_JAR_TARGET}.jar)
  add_custom_command(
    OUTPUT ${jar}
    COMMAND ${CMAKE_COMMAND} -E rm -rf ${class_root}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${class_root} ${CMAKE_BINARY_DIR}/share/java
    COMMAND ${Java_JAVAC_EXECUTABLE} -nowarn -source 11 -target 11 -cp ${LCM_JAR} -d ${class_root} ${java_sources} ${ARG_JAVA_SOURCES}
    COMMAND ${Java_JAR_EXECUTABLE} cf ${jar} -C ${class_root} .
    DEPENDS ${java_sources} ${ARG_JAVA_SOURCES}
    COMMENT "javac + jar ${ARG_JAR_TARGET}.jar"
    VERBATIM)
  add_custom_target(${ARG_JAR_TARGET} ALL DEPENDS ${jar})
  set(${ARG_JAR_TARGET}_JAR ${jar} PARENT_SCOPE)
endfunction()
