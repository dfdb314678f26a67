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
  # The same with the hierarchical operator: cluster links must not carry light through walls either (a
  # cluster spanning the shut room and a lit one is linked only where every ray agrees, and rooms behind walls
  # get no link at all).
  add_test(NAME FloorPlanShutRoomStaysDarkHierarchical
    COMMAND sh -c "\"$1\" solve \"$2\" -o \"$3\" --operator hierarchical --quiet && \"$4\" \"$5\" --check \"$3\""
      sh $<TARGET_FILE:lambert> ${PROJECT_SOURCE_DIR}/examples/floorplan.obj ${CMAKE_CURRENT_BINARY_DIR}/leak_floorplan_h.vtu
      ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/make_floorplan.py)
  set_tests_properties(FloorPlanShutRoomStaysDarkHierarchical PROPERTIES LABELS "end-to-end" TIMEOUT 600)
  # The hierarchy's far-field kernels are generated (scripts/gen_far_field3.py) and committed: the committed file
  # must be what the script writes, so that neither is edited without the other.
  add_test(NAME GeneratedFarFieldKernelsMatchTheirScript
    COMMAND sh -c "\"$1\" \"$2\" | cmp -s - \"$3\""
      sh ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/gen_far_field3.py
      ${PROJECT_SOURCE_DIR}/formfactor/src/isa/far_field3.inc)
  set_tests_properties(GeneratedFarFieldKernelsMatchTheirScript PROPERTIES TIMEOUT 60)
endif()

# The quick accuracy study (issue: speed against error): the CSV must be well formed, errors must fall as
# meshes are refined, the adaptive rule must meet its tolerance, and the plots must render. Debian's
# /usr/bin/python3 has python3-matplotlib (a pyenv python first on PATH may not).
find_program(LAMBERT_DEBIAN_PYTHON python3 PATHS /usr/bin NO_DEFAULT_PATH)
if(LAMBERT_DEBIAN_PYTHON)
  add_test(NAME QuickStudyIsWellFormedAndErrorsFallUnderRefinement
    COMMAND sh -c "\"$1\" study --quick --quiet --out \"$2\" && \"$3\" \"$4\" \"$2/study.csv\" --check --out \"$2\""
      sh $<TARGET_FILE:lambert> ${CMAKE_CURRENT_BINARY_DIR}/study-quick ${LAMBERT_DEBIAN_PYTHON}
      ${PROJECT_SOURCE_DIR}/scripts/plot_study.py)
  set_tests_properties(QuickStudyIsWellFormedAndErrorsFallUnderRefinement PROPERTIES LABELS "end-to-end" TIMEOUT 300)
endif()

# Issue 11, "round-off is not an error": the public urban geometry (6,612 triangles, grazing pairs whose
# form factors come out at -1e-16 .. -1e-24) must give its form factors with exit 0: entries within their
# error bound of [0, 1] are round-off (counted), not failure. ~20 s on 2 cores. Skipped (77) when
# ../shared/models is not beside the repository.
add_test(NAME UdalesShapeFormFactorsAreNotRefusedForRoundOff
  COMMAND sh -c "test -f \"$2\" || exit 77; \"$1\" formfactors \"$2\" -o \"$3\" --stats \"$4\" --quiet && grep -q '\"entries_outside_unit\": 0' \"$4\""
    sh $<TARGET_FILE:lambert> ${PROJECT_SOURCE_DIR}/../shared/models/udales_shape.obj
    ${CMAKE_CURRENT_BINARY_DIR}/udales_F.csv ${CMAKE_CURRENT_BINARY_DIR}/udales_stats.json)
set_tests_properties(UdalesShapeFormFactorsAreNotRefusedForRoundOff PROPERTIES LABELS "end-to-end" TIMEOUT 600
  SKIP_RETURN_CODE 77)

# The README's storey example solves and passes its own checks (exit 0). Its partition is two-sided: the two
# coincident patches are both in the Embree scene of the independent row-sum check, which may report the back
# one first; counting that as "missing light" failed the cabinet's row (0.57 found against 1.0) before the check
# took the side facing the ray.
add_test(NAME StoreyExampleSolvesAndPassesItsChecks
  COMMAND $<TARGET_FILE:lambert> solve ${PROJECT_SOURCE_DIR}/examples/storey.obj -o ${CMAKE_CURRENT_BINARY_DIR}/storey.vtu --quiet)
set_tests_properties(StoreyExampleSolvesAndPassesItsChecks PROPERTIES LABELS "end-to-end" TIMEOUT 120)
# The STL storey: imprinting leaves a 500:1 floor sliver touching a table leg and tapered leg faces, whose
# visible fractions the ray samples once biased high (row sums 1.032 and 1.023: exit 3).
add_test(NAME StoreyStlExampleSolvesAndPassesItsChecks
  COMMAND $<TARGET_FILE:lambert> solve ${PROJECT_SOURCE_DIR}/examples/storey.stl
          --materials ${PROJECT_SOURCE_DIR}/examples/storey_stl.json -o ${CMAKE_CURRENT_BINARY_DIR}/storey_stl.vtu --quiet)
set_tests_properties(StoreyStlExampleSolvesAndPassesItsChecks PROPERTIES LABELS "end-to-end" TIMEOUT 120)
