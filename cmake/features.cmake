# The optional dependencies of roe (issue 38: `make demo` needs neither OpenCV nor Ceres). Each is a cache
# variable ROE_WITH_<X> = AUTO (default: use it when found), ON (required: configure fails naming the Debian
# package) or OFF (not used). What a build has is compiled into roe (generated/roe/features.hpp, from
# cmake/features.hpp.in) and listed by `roe --version`; a command whose dependency is missing still exists
# and answers with the package to install and the option to rebuild with (exit 2).

# roe_optional_package(OPTION RESULT DEBIAN_PACKAGE PURPOSE <find_package arguments>): sets RESULT to ON
# or OFF. A macro, so that find_package's variables (OpenCV_INCLUDE_DIRS, TORCH_LIBRARIES) stay visible.
macro(roe_optional_package _option _result _debian _purpose _package)
  set(${_option} AUTO CACHE STRING "${_purpose}: AUTO, ON or OFF")
  set_property(CACHE ${_option} PROPERTY STRINGS AUTO ON OFF)
  string(TOUPPER "${${_option}}" _roe_mode)
  if(NOT _roe_mode MATCHES "^(AUTO|ON|OFF)$")
    message(FATAL_ERROR "${_option}=${${_option}}: expected AUTO, ON or OFF")
  endif()
  set(${_result} OFF)
  if(NOT _roe_mode STREQUAL "OFF")
    find_package(${_package} ${ARGN} QUIET)
    if(${_package}_FOUND)
      set(${_result} ON)
    elseif(_roe_mode STREQUAL "ON")
      message(FATAL_ERROR "${_option}=ON but ${_package} was not found (${_purpose}). Install ${_debian} "
                          "(scripts/install-deps.sh test), or configure with -D${_option}=AUTO to build "
                          "without it.")
    endif()
  endif()
  message(STATUS "roe: ${_package} (${_purpose}): ${${_result}} (${_option}=${_roe_mode})")
endmacro()

# roe_tests_wanted(RESULT FOUND_VAR DEBIAN_PACKAGE ...): whether to configure the tests, from ROE_BUILD_TESTS
# (AUTO, ON, OFF), Catch2 and the FOUND_VARs of the optional libraries they exercise. AUTO without one of
# them configures no tests and says which packages are missing; ON fails naming them.
macro(roe_tests_wanted _result)
  string(TOUPPER "${ROE_BUILD_TESTS}" _roe_mode)
  if(_roe_mode MATCHES "^(1|TRUE|YES)$")  # a cache from before AUTO existed (a BOOL option)
    set(_roe_mode ON)
  elseif(_roe_mode MATCHES "^(0|FALSE|NO)$")
    set(_roe_mode OFF)
  elseif(NOT _roe_mode MATCHES "^(AUTO|ON|OFF)$")
    message(FATAL_ERROR "ROE_BUILD_TESTS=${ROE_BUILD_TESTS}: expected AUTO, ON or OFF")
  endif()
  set(${_result} OFF)
  if(NOT _roe_mode STREQUAL "OFF")
    set(_roe_missing)
    find_package(Catch2 2 QUIET)
    if(NOT Catch2_FOUND)
      list(APPEND _roe_missing catch2)
    endif()
    set(_roe_args ${ARGN})
    while(_roe_args)
      list(POP_FRONT _roe_args _roe_var _roe_pkg)
      if(NOT ${_roe_var})
        list(APPEND _roe_missing ${_roe_pkg})
      endif()
    endwhile()
    string(JOIN " " _roe_missing ${_roe_missing})
    if(NOT _roe_missing)
      set(${_result} ON)
    elseif(_roe_mode STREQUAL "ON")
      message(FATAL_ERROR "ROE_BUILD_TESTS=ON: the tests need ${_roe_missing} (scripts/install-deps.sh test), "
                          "with the optional libraries enabled (-DROE_WITH_OPENCV=ON -DROE_WITH_CERES=ON)")
    else()
      message(STATUS "roe: tests not configured: they need ${_roe_missing} (scripts/install-deps.sh test)")
    endif()
  endif()
endmacro()
