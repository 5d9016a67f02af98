# The SYCL backend's parity tests, as their own executable so that they build beside the main suite; in a build
# without SYCL they compile and report themselves skipped.
find_package(GTest REQUIRED)
include(GoogleTest)

add_executable(pt_sycl_tests ${CMAKE_CURRENT_LIST_DIR}/test_sycl_backend.cpp)
target_link_libraries(pt_sycl_tests PRIVATE pt_core pt_backends GTest::gtest GTest::gtest_main)
target_compile_definitions(pt_sycl_tests PRIVATE
  PT_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  PT_PATHTRACER_BINARY="$<TARGET_FILE:pathtracer>")
target_compile_options(pt_sycl_tests PRIVATE -Wall -Wextra)
add_dependencies(pt_sycl_tests pathtracer)
gtest_discover_tests(pt_sycl_tests DISCOVERY_TIMEOUT 120 PROPERTIES TIMEOUT 600)
