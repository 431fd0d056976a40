# The hostile-input catalogue (docs/TESTING.md, "Hostile inputs"): scripts/hostile-catalogue.py makes
# about 180 damaged inputs and runs the roe binary on each under 10 s and 1 GB; every one must end in
# exit 0 (where documented), 1 or 2. Two cases at a time, to share the machine.
if(ROE_TESTS_ON AND NOT ROE_FUZZ)
  find_package(Python3 COMPONENTS Interpreter)
  if(Python3_Interpreter_FOUND)
    add_test(NAME cli/hostile-catalogue
             COMMAND ${Python3_EXECUTABLE} ${CMAKE_SOURCE_DIR}/scripts/hostile-catalogue.py $<TARGET_FILE:roe> --jobs 2)
    set_tests_properties(cli/hostile-catalogue PROPERTIES LABELS cli TIMEOUT 900)
  endif()
endif()
