# The layer rule: the core and algorithm libraries know nothing of LCM, so
# the same code runs as a process over UDP multicast, in one process under
# vslam-replay, and under unit tests. Only the bus, the stage adapters and the
# tools may link it. vslam_check_layers() fails the configure step naming the
# library and the path by which it reaches LCM.

# Libraries that may not depend on LCM, directly or through others.
set(VSLAM_LCM_FREE_TARGETS vslam_util vslam_config vslam_odometry vslam_world vslam_frontend
    vslam_backend vslam_appearance vslam_landmark_db vslam_eval vslam_capture vslam_odometry_bridge
    vslam_calibration vslam_status vslam_viewer)
# What "LCM" is: the library, and the generated message types.
set(VSLAM_LCM_TARGETS PkgConfig::LCM vslam_lcmtypes vslam_bus)

# Sets ${out} to the path "a -> b -> ..." from `target` to an LCM target, or "".
function(vslam_lcm_path target out)
  set(visited "")
  set(queue "${target}")
  set(path_${target} "${target}")
  while(queue)
    list(POP_FRONT queue current)
    if(current IN_LIST visited)
      continue()
    endif()
    list(APPEND visited ${current})
    if(NOT TARGET ${current})
      continue()
    endif()
    get_target_property(type ${current} TYPE)
    set(deps "")
    if(NOT type STREQUAL "INTERFACE_LIBRARY")
      get_target_property(direct ${current} LINK_LIBRARIES)
      if(direct)
        list(APPEND deps ${direct})
      endif()
    endif()
    get_target_property(iface ${current} INTERFACE_LINK_LIBRARIES)
    if(iface)
      list(APPEND deps ${iface})
    endif()
    foreach(dep IN LISTS deps)
      string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" dep "${dep}")
      if(dep IN_LIST VSLAM_LCM_TARGETS)
        set(${out} "${path_${current}} -> ${dep}" PARENT_SCOPE)
        return()
      endif()
      if(NOT DEFINED path_${dep})
        set(path_${dep} "${path_${current}} -> ${dep}")
      endif()
      list(APPEND queue ${dep})
    endforeach()
  endwhile()
  set(${out} "" PARENT_SCOPE)
endfunction()

function(vslam_check_layers)
  foreach(target IN LISTS VSLAM_LCM_FREE_TARGETS ARGN)
    vslam_lcm_path(${target} path)
    if(path)
      message(FATAL_ERROR "layer rule: ${target} may not depend on LCM, but links it: ${path} "
                          "(cmake/VslamLayers.cmake)")
    endif()
  endforeach()
endfunction()
