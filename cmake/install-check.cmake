# Install-time checks for `cmake --install` (issue 38), included by the install section of CMakeLists.txt.
#
# roe_install_check(MAIN HELPER...): the first install step. Fails before anything is copied when the MAIN
# executable is not built (a `cmake --install` of a folder that was only configured), naming the command
# that builds it.
function(roe_install_check main)
  string(JOIN " " _helpers ${ARGN})
  install(CODE "
    if(NOT EXISTS \"$<TARGET_FILE:${main}>\")
      message(FATAL_ERROR \"roe install: $<TARGET_FILE:${main}> is not built; nothing was installed. \"
                          \"Build it first: cmake --build ${CMAKE_BINARY_DIR} --target ${main} ${_helpers} \"
                          \"(or run make install PREFIX=...)\")
    endif()")
endfunction()

# roe_install_report(HELPER COMMAND [HELPER COMMAND]...): the last install step. For each helper that was
# not built (so skipped: installed OPTIONAL), a warning naming the command that will be unavailable in the
# prefix and how to add it; everything else was installed.
function(roe_install_report)
  set(_code "set(_missing \"\")\n")
  set(_args ${ARGN})
  set(_targets)
  while(_args)
    list(POP_FRONT _args _helper _command)
    list(APPEND _targets ${_helper})
    string(APPEND _code "if(NOT EXISTS \"$<TARGET_FILE:${_helper}>\")\n"
                        "  string(APPEND _missing \"\\n  ${_helper} (${_command})\")\n"
                        "endif()\n")
  endwhile()
  string(JOIN " " _targets ${_targets})
  string(APPEND _code "if(_missing)\n"
    "  message(WARNING \"roe install: installed roe, its configs and scripts into \${CMAKE_INSTALL_PREFIX}; \"\n"
    "    \"these helpers are not built, so their commands are not available there:\${_missing}\\n\"\n"
    "    \"Add them with: cmake --build ${CMAKE_BINARY_DIR} --target ${_targets} && \"\n"
    "    \"cmake --install ${CMAKE_BINARY_DIR} --prefix \${CMAKE_INSTALL_PREFIX} (or make install PREFIX=...)\")\n"
    "endif()\n")
  install(CODE "${_code}")
endfunction()
