# Helpers shared by every module's CMakeLists.txt.
#
# anchormap_module(NAME target DEPS ...): a static library of the folder's *.cc files
#   (without *_test.cc and *_main.cc), include root = repository root; each foo_test.cc
#   becomes a GoogleTest executable registered with ctest; each foo_main.cc becomes
#   build/bin/anchormap-<foo with '_' -> '-'> (override the name with MAIN_PREFIX).
# A header-only folder (no .cc) gives an INTERFACE library.

function(anchormap_module)
  cmake_parse_arguments(ARG "" "NAME;MAIN_PREFIX" "DEPS;TEST_DEPS" ${ARGN})
  file(GLOB all_sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
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

  if(lib_sources)
    add_library(${ARG_NAME} STATIC ${lib_sources})
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
    target_compile_definitions(${test_target} PRIVATE
        ANCHORMAP_DEFAULT_DATA_DIR="${ANCHORMAP_DATA_DIR}"
        ANCHORMAP_BINARY_DIR="${CMAKE_BINARY_DIR}"
        ANCHORMAP_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
    set_target_properties(${test_target} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
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
  endforeach()
endfunction()
