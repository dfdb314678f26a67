# Warnings and optimisation flags in one INTERFACE target that every lambert target links.
add_library(lambert_warnings INTERFACE)
target_compile_options(lambert_warnings INTERFACE
  -Wall -Wextra -Wpedantic
  -Wshadow              # shadowed names hide bugs in numerical loops
  -Wno-unused-parameter # virtual interfaces (Visibility, TransportOperator) keep documented names
)
add_library(lambert_opt INTERFACE)
if(LAMBERT_NATIVE)
  target_compile_options(lambert_opt INTERFACE -march=native)
endif()

# One library per module: lambert_add_module(NAME SOURCES...) -> target lambert_NAME, alias lambert::NAME
function(lambert_add_module name)
  add_library(lambert_${name} STATIC ${ARGN})
  add_library(lambert::${name} ALIAS lambert_${name})
  target_include_directories(lambert_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(lambert_${name} PRIVATE lambert_warnings lambert_opt)
  set_target_properties(lambert_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()
