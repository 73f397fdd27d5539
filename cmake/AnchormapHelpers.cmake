# Helpers shared by every module's CMakeLists.txt.
#
# anchormap_module(NAME target DEPS ...): a static library of the folder's *.cc files
#   (without *_test.cc and *_main.cc), include root = repository root; each foo_test.cc
#   becomes a GoogleTest executable registered with ctest; each foo_main.cc becomes
#   build/bin/anchormap-<foo with '_' -> '-'> (override the name with MAIN_PREFIX).
#   COMPILE_OPTIONS: options of the library's own files (not its tests'), which then do
#   without the precompiled header (anchormap_precompiled_headers()).
# A header-only folder (no .cc) gives an INTERFACE library.
#
# Layering: every module records its folder, its DEPS and TEST_DEPS. After all folders
# are added, anchormap_check_layering() (root CMakeLists.txt) makes a build step that reads
# each source's #include lines and fails the build when a file includes a header of a
# module its own module does not depend on (directly or through its DEPS; a test may also
# use its TEST_DEPS). So agent/ including common/bus/ fails to build, not only to link.

# anchormap_precompiled_headers(): the two precompiled headers (ANCHORMAP_PCH), made once by
# the root CMakeLists.txt (its folder's compile options are the global ones):
# anchormap_pch_library (Eigen's core and the standard headers most files include) for the
# libraries and programs, anchormap_pch_test (the same and GoogleTest) for the test programs.
# Parsing them was a quarter to a half of a file's compile CPU (docs/ARCHITECTURE.md, "CI's
# time"). Clang takes a precompiled header only with the same flags and the same value of
# each macro, and GCC takes some options from the precompiled header over the command line's
# (-ffp-contract=off was lost so: the scan matcher's vector paths fused multiply-adds and lost
# their scalar twins' bits): a file with other options opts out (source property
# SKIP_PRECOMPILE_HEADERS), and so does a module's library given COMPILE_OPTIONS.
set(ANCHORMAP_PCH_HEADERS <Eigen/Core> <algorithm> <array> <cmath> <cstdint> <cstdio> <cstdlib>
    <cstring> <filesystem> <fstream> <functional> <limits> <map> <memory> <optional> <random>
    <set> <sstream> <string> <unordered_map> <utility> <vector>)
function(anchormap_precompiled_headers)
  foreach(kind library test)
    set(stub ${CMAKE_BINARY_DIR}/anchormap_pch_${kind}.cc)
    if(NOT EXISTS ${stub})
      file(WRITE ${stub} "// Hosts a precompiled header (cmake/AnchormapHelpers.cmake).\n")
    endif()
    add_library(anchormap_pch_${kind} OBJECT ${stub})
    target_link_libraries(anchormap_pch_${kind} PRIVATE Eigen3::Eigen)
  endforeach()
  target_precompile_headers(anchormap_pch_library PRIVATE ${ANCHORMAP_PCH_HEADERS})
  target_link_libraries(anchormap_pch_test PRIVATE GTest::gtest)
  anchormap_test_definitions(anchormap_pch_test)
  target_precompile_headers(anchormap_pch_test PRIVATE <gtest/gtest.h> ${ANCHORMAP_PCH_HEADERS})
endfunction()

# The definitions every test program compiles with.
function(anchormap_test_definitions target)
  target_compile_definitions(${target} PRIVATE
      ANCHORMAP_DEFAULT_DATA_DIR="${ANCHORMAP_DATA_DIR}"
      ANCHORMAP_BINARY_DIR="${CMAKE_BINARY_DIR}"
      ANCHORMAP_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
endfunction()

function(anchormap_module)
  cmake_parse_arguments(ARG "" "NAME;MAIN_PREFIX" "DEPS;TEST_DEPS;COMPILE_OPTIONS" ${ARGN})
  file(GLOB all_sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  file(GLOB all_headers CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.h)
  file(RELATIVE_PATH module_dir ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  set_property(GLOBAL APPEND PROPERTY ANCHORMAP_MODULES ${ARG_NAME})
  set_property(GLOBAL PROPERTY ANCHORMAP_DIR_${ARG_NAME} ${module_dir})
  set_property(GLOBAL PROPERTY ANCHORMAP_DEPS_${ARG_NAME} ${ARG_DEPS})
  set_property(GLOBAL PROPERTY ANCHORMAP_TEST_DEPS_${ARG_NAME} ${ARG_TEST_DEPS})
  set(lib_sources "")
  set(test_sources "")
  set(main_sources "")
  foreach(src ${all_sources})
    if(src MATCHES "_test\\.cc$")
      list(APPEND test_sources ${src})
    elseif(src MATCHES "_main\\.cc$")
      list(APPEND main_sources ${src})
    else()
      list(APPEND lib_sources ${src})
    endif()
  endforeach()
  set_property(GLOBAL PROPERTY ANCHORMAP_SOURCES_${ARG_NAME} ${lib_sources} ${main_sources}
                                                             ${all_headers})
  set_property(GLOBAL PROPERTY ANCHORMAP_TEST_SOURCES_${ARG_NAME} ${test_sources})

  if(lib_sources)
    add_library(${ARG_NAME} STATIC ${lib_sources})
    target_compile_options(${ARG_NAME} PRIVATE ${ARG_COMPILE_OPTIONS})
    if(ANCHORMAP_PCH AND NOT ARG_COMPILE_OPTIONS)
      target_precompile_headers(${ARG_NAME} REUSE_FROM anchormap_pch_library)
    endif()
    target_include_directories(${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(${ARG_NAME} PUBLIC ${ARG_DEPS})
  else()
    add_library(${ARG_NAME} INTERFACE)
    target_include_directories(${ARG_NAME} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(${ARG_NAME} INTERFACE ${ARG_DEPS})
  endif()

  foreach(src ${test_sources})
    get_filename_component(stem ${src} NAME_WE)
    set(test_target ${ARG_NAME}_${stem})
    add_executable(${test_target} ${src})
    target_link_libraries(${test_target} PRIVATE ${ARG_NAME} ${ARG_TEST_DEPS} GTest::gtest GTest::gtest_main)
    anchormap_test_definitions(${test_target})
    set_target_properties(${test_target} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
    if(ANCHORMAP_PCH)
      target_precompile_headers(${test_target} REUSE_FROM anchormap_pch_test)
    endif()
    gtest_discover_tests(${test_target} DISCOVERY_TIMEOUT 120
                         PROPERTIES ENVIRONMENT "ANCHORMAP_BINARY_DIR=${CMAKE_BINARY_DIR}")
  endforeach()

  foreach(src ${main_sources})
    get_filename_component(stem ${src} NAME_WE)
    string(REGEX REPLACE "_main$" "" stem ${stem})
    string(REPLACE "_" "-" stem ${stem})
    if(ARG_MAIN_PREFIX)
      set(exe_name ${ARG_MAIN_PREFIX}${stem})
    else()
      set(exe_name anchormap-${stem})
    endif()
    add_executable(${exe_name} ${src})
    target_link_libraries(${exe_name} PRIVATE ${ARG_NAME})
    if(ANCHORMAP_PCH)
      target_precompile_headers(${exe_name} REUSE_FROM anchormap_pch_library)
    endif()
  endforeach()
endfunction()

# anchormap_example(NAME name SOURCE file DEPS ...): a short program that shows the API,
# built as build/bin/anchormap-example-<name> and run by ctest (it exits non-zero when one
# of its own checks fails). Its includes are checked like a module's.
function(anchormap_example)
  cmake_parse_arguments(ARG "" "NAME;SOURCE" "DEPS" ${ARGN})
  set(target anchormap-example-${ARG_NAME})
  add_executable(${target} ${ARG_SOURCE})
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(${target} PRIVATE ${ARG_DEPS})
  add_test(NAME example_${ARG_NAME} COMMAND ${target})
  file(RELATIVE_PATH module_dir ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  set_property(GLOBAL APPEND PROPERTY ANCHORMAP_MODULES ${target})
  set_property(GLOBAL PROPERTY ANCHORMAP_DIR_${target} ${module_dir})
  set_property(GLOBAL PROPERTY ANCHORMAP_DEPS_${target} ${ARG_DEPS})
  set_property(GLOBAL PROPERTY ANCHORMAP_SOURCES_${target}
                               ${CMAKE_CURRENT_SOURCE_DIR}/${ARG_SOURCE})
endfunction()

# The anchormap modules `target` may use: itself and its DEPS, transitively.
function(anchormap_closure out)
  set(todo ${ARGN})
  set(seen "")
  while(todo)
    list(POP_FRONT todo t)
    if(t IN_LIST seen)
      continue()
    endif()
    list(APPEND seen ${t})
    get_property(deps GLOBAL PROPERTY ANCHORMAP_DEPS_${t})
    list(APPEND todo ${deps})
  endwhile()
  set(${out} ${seen} PARENT_SCOPE)
endfunction()

function(anchormap_check_layering)
  get_property(modules GLOBAL PROPERTY ANCHORMAP_MODULES)
  # A library's own compile options and the shared precompiled header do not mix (GCC takes
  # some options from the header): give them to anchormap_module(COMPILE_OPTIONS) instead.
  # Warning options (-W...) change no code and may differ.
  if(TARGET anchormap_pch_library)
    get_target_property(pch_options anchormap_pch_library COMPILE_OPTIONS)
    list(FILTER pch_options EXCLUDE REGEX "^-W")
    foreach(m ${modules})
      get_target_property(pch ${m} PRECOMPILE_HEADERS_REUSE_FROM)
      if(pch)
        get_target_property(options ${m} COMPILE_OPTIONS)
        list(FILTER options EXCLUDE REGEX "^-W")
        if(NOT "${options}" STREQUAL "${pch_options}")
          message(FATAL_ERROR "${m}: compile options (${options}) other than the precompiled "
                              "header's (${pch_options}); pass them as "
                              "anchormap_module(... COMPILE_OPTIONS ...)")
        endif()
      endif()
    endforeach()
  endif()
  # Module folders, and the generated message headers (anchormap/, bot_core/) and LCM's own
  # (lcm/), which belong to the lcmtypes and lcm targets.
  set(table "set(MODULE_DIRS \"lcmtypes_generated/anchormap;lcmtypes_generated/bot_core;lcm")
  set(owners "set(OWNER_lcmtypes_generated/anchormap anchormap_lcmtypes)\n")
  string(APPEND owners "set(OWNER_lcmtypes_generated/bot_core anchormap_lcmtypes)\n")
  string(APPEND owners "set(OWNER_lcm anchormap_lcm)\n")
  foreach(m ${modules})
    get_property(dir GLOBAL PROPERTY ANCHORMAP_DIR_${m})
    string(APPEND table ";${dir}")
    string(APPEND owners "set(OWNER_${dir} ${m})\n")
  endforeach()
  string(APPEND table "\")\n")
  set(checks "")
  foreach(m ${modules})
    get_property(deps GLOBAL PROPERTY ANCHORMAP_DEPS_${m})
    get_property(test_deps GLOBAL PROPERTY ANCHORMAP_TEST_DEPS_${m})
    anchormap_closure(allowed ${m} ${deps})
    anchormap_closure(test_allowed ${m} ${deps} ${test_deps})
    # lcmtypes' INTERFACE target links anchormap_lcm.
    if(anchormap_lcmtypes IN_LIST allowed)
      list(APPEND allowed anchormap_lcm)
    endif()
    if(anchormap_lcmtypes IN_LIST test_allowed)
      list(APPEND test_allowed anchormap_lcm)
    endif()
    get_property(sources GLOBAL PROPERTY ANCHORMAP_SOURCES_${m})
    get_property(test_sources GLOBAL PROPERTY ANCHORMAP_TEST_SOURCES_${m})
    string(APPEND checks "check(${m} \"${allowed}\" \"${sources}\")\n")
    string(APPEND checks "check(${m} \"${test_allowed}\" \"${test_sources}\")\n")
  endforeach()
  file(WRITE ${CMAKE_BINARY_DIR}/layering_table.cmake "${table}${owners}${checks}")
  add_custom_target(anchormap_layering ALL
                    COMMAND ${CMAKE_COMMAND} -DTABLE=${CMAKE_BINARY_DIR}/layering_table.cmake
                            -P ${PROJECT_SOURCE_DIR}/cmake/CheckLayering.cmake
                    COMMENT "Checking that every #include follows the module dependencies"
                    VERBATIM)
  foreach(m ${modules})
    add_dependencies(${m} anchormap_layering)
  endforeach()
endfunction()
