# Script-driven tests beyond GoogleTest.
include(${CMAKE_CURRENT_SOURCE_DIR}/paraview.cmake OPTIONAL)
