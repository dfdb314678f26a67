# Script-driven tests beyond GoogleTest.
include(${CMAKE_CURRENT_SOURCE_DIR}/paraview.cmake OPTIONAL)

# Leak test on the bundled floor plan: the shut storage room shares walls with four lit rooms (floors
# and walls meshed independently, patches crossing each other's planes under the walls) and must stay
# exactly dark. scripts/make_floorplan.py --check maps face_id to rooms and fails on any light there.
find_package(Python3 COMPONENTS Interpreter)
if(Python3_FOUND)
  add_test(NAME FloorPlanShutRoomStaysDark
    COMMAND sh -c "\"$1\" solve \"$2\" -o \"$3\" --quiet && \"$4\" \"$5\" --check \"$3\""
      sh $<TARGET_FILE:lambert> ${PROJECT_SOURCE_DIR}/examples/floorplan.obj ${CMAKE_CURRENT_BINARY_DIR}/leak_floorplan.vtu
      ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/make_floorplan.py)
  set_tests_properties(FloorPlanShutRoomStaysDark PROPERTIES LABELS "end-to-end" TIMEOUT 600)
endif()
