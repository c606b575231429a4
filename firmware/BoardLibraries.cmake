# One set of components, many boards: the core and the CANopen engine are compiled against one
# board's generated headers (board/fields.hpp sizes the message board, the object dictionary...),
# so each board links its own build of the same sources. fw_core, fw_canopen and the Linux
# platform libraries are the joint's (the default table); hil_library_for_board() makes another
# board's copy of one of them.

# TARGET: a static library with FROM's sources, include directories and compile options, linked
# to PROTOCOL (a hil_board_protocol() target) and to LINKS (that board's copies of what FROM
# links besides its board protocol).
function(hil_library_for_board target from protocol)
  get_target_property(sources ${from} SOURCES)
  get_target_property(source_dir ${from} SOURCE_DIR)
  set(absolute_sources "")
  foreach(source IN LISTS sources)
    cmake_path(ABSOLUTE_PATH source BASE_DIRECTORY ${source_dir} OUTPUT_VARIABLE source)
    list(APPEND absolute_sources ${source})
  endforeach()
  add_library(${target} STATIC ${absolute_sources})
  get_target_property(includes ${from} INTERFACE_INCLUDE_DIRECTORIES)
  if(includes)
    target_include_directories(${target} PUBLIC ${includes})
  endif()
  get_target_property(options ${from} COMPILE_OPTIONS)
  if(options)
    target_compile_options(${target} PRIVATE ${options})
  endif()
  target_link_libraries(${target} PUBLIC ${protocol} ${ARGN})
endfunction()
