# Issue 15: the mutation fuzzer for the readers (tests/fuzz/fuzz_readers.cpp) with its committed seed corpus,
# a short run (fixed seed, so a failure reproduces) and a replay of every committed reproducer.
# scripts/sanitize.sh builds the same two tests (and test_readers) with ASan + UBSan.
add_executable(fuzz_readers ${CMAKE_CURRENT_LIST_DIR}/fuzz_readers.cpp)
target_link_libraries(fuzz_readers PRIVATE lambert::io lambert_warnings)
set(LAMBERT_FUZZ_RUNS 3000 CACHE STRING "Mutated inputs per short fuzz run (CTest FuzzReadersShort)")
add_test(NAME FuzzReadersShort
  COMMAND fuzz_readers ${CMAKE_CURRENT_LIST_DIR}/corpus --runs ${LAMBERT_FUZZ_RUNS} --seed 15
  WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
add_test(NAME FuzzReadersReplayIssue15Reproducers
  COMMAND fuzz_readers ${CMAKE_CURRENT_LIST_DIR}/corpus --replay ${CMAKE_CURRENT_LIST_DIR}/corpus/regressions
  WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
set_tests_properties(FuzzReadersShort FuzzReadersReplayIssue15Reproducers PROPERTIES LABELS "fuzz" TIMEOUT 300)

# The reader, preparation and output-transaction tests in one executable that needs only lambert::io (and
# lambert::mesh), for the ASan + UBSan build of scripts/sanitize.sh: building it does not build the
# form-factor, solver and VTK parts (the full project under ASan takes several times longer on 2 cores).
add_executable(sanitize_tests EXCLUDE_FROM_ALL
  ${PROJECT_SOURCE_DIR}/tests/test_readers.cpp ${PROJECT_SOURCE_DIR}/tests/test_prepare.cpp
  ${PROJECT_SOURCE_DIR}/tests/test_output_transaction.cpp)
target_link_libraries(sanitize_tests PRIVATE lambert::io GTest::gtest GTest::gtest_main lambert_warnings)
target_compile_definitions(sanitize_tests PRIVATE LAMBERT_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
