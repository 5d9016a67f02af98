# Registers one CTest test per GoogleTest suite of an executable, run by CTest when it reads the test list.
# Sanitizer builds use it: there each process spends about 0.4 s starting (shadow memory, registering globals) and
# scanning for leaks at exit, so one process per suite instead of one per test saves minutes on a small machine.
# Release builds keep one CTest test per GoogleTest test (gtest_discover_tests), for the finest report.

function(pt_add_test_suites executable timeout)
  execute_process(COMMAND "${executable}" --gtest_list_tests
                  OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE status TIMEOUT 120)
  if(NOT status EQUAL 0)
    # Listing failed: one failing test says so, rather than a silently empty suite.
    add_test("${executable}.ListingFailed" "${executable}" --gtest_list_tests)
    return()
  endif()
  string(REPLACE "\n" ";" lines "${listing}")
  foreach(line IN LISTS lines)
    # A suite's line starts in column 0 and ends its name with '.', e.g. "Bvh/0.  # TypeParam = float";
    # its tests' lines are indented.
    if(line MATCHES "^([A-Za-z_][^ .]*)\\.")
      set(suite "${CMAKE_MATCH_1}")
      add_test("${suite}" "${executable}" "--gtest_filter=${suite}.*")
      set_tests_properties("${suite}" PROPERTIES TIMEOUT ${timeout})
    endif()
  endforeach()
endfunction()
