# Workaround for ROS 2 Jazzy installed from PyPI wheels (see docs/architecture.md, "How setup works here").
#
# The wheels' exported CMake targets (e.g. std_msgs::std_msgs__rosidl_generator_py) name
# the wheel build machine's Python include folder, /opt/python/cp311-cp311/include/python3.11,
# which does not exist here, and CMake's generate step refuses targets with missing
# INTERFACE_INCLUDE_DIRECTORIES. Passed as -DCMAKE_PROJECT_INCLUDE=<this file>, it defers,
# to the end of the top-level CMakeLists.txt (after every find_package), a pass that drops
# non-existent folders from every imported target. Not needed (and not used) with an apt
# install of ROS 2.

function(_boom_drop_missing_include_dirs_in dir)
  get_property(_targets DIRECTORY "${dir}" PROPERTY IMPORTED_TARGETS)
  foreach(_t IN LISTS _targets)
    get_target_property(_incs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_incs)
      set(_kept "")
      set(_changed FALSE)
      foreach(_inc IN LISTS _incs)
        if(_inc MATCHES "^\\$<" OR EXISTS "${_inc}")
          list(APPEND _kept "${_inc}")
        else()
          set(_changed TRUE)
        endif()
      endforeach()
      if(_changed)
        set_property(TARGET ${_t} PROPERTY INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
      endif()
    endif()
  endforeach()
  get_property(_subdirs DIRECTORY "${dir}" PROPERTY SUBDIRECTORIES)
  foreach(_sub IN LISTS _subdirs)
    _boom_drop_missing_include_dirs_in("${_sub}")
  endforeach()
endfunction()

function(_boom_drop_missing_include_dirs)
  _boom_drop_missing_include_dirs_in("${CMAKE_SOURCE_DIR}")
endfunction()

if(NOT _BOOM_DROP_MISSING_INCLUDE_DIRS_DEFERRED)
  set(_BOOM_DROP_MISSING_INCLUDE_DIRS_DEFERRED TRUE)
  cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _boom_drop_missing_include_dirs)
endif()
