# rb_add_module(NAME SOURCES src... [PUBLIC_DEPS t...] [PRIVATE_DEPS t...])
# One static library per module folder, target name rb_<NAME>, includes rooted at the repository.
function(rb_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  if(NOT ARG_SOURCES)
    # A module with headers only so far.
    add_library(rb_${name} INTERFACE)
    target_include_directories(rb_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(rb_${name} INTERFACE ${ARG_PUBLIC_DEPS})
    return()
  endif()
  add_library(rb_${name} STATIC ${ARG_SOURCES})
  target_include_directories(rb_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(rb_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  rb_set_warnings(rb_${name})
endfunction()

# rb_add_test(MODULE SOURCES src... [DEPS t...]): one GoogleTest executable per module, CTest names
# "<module>/<test>" through gtest_discover_tests; tests run from the repository root so that
# tests/data and recordings/ paths are relative to it.
function(rb_add_test module)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  if(NOT RANGEBAYES_BUILD_TESTS)
    return()
  endif()
  add_executable(test_${module} ${ARG_SOURCES})
  target_link_libraries(test_${module} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_definitions(test_${module} PRIVATE RB_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  rb_set_warnings(test_${module})
  rb_test_timeout(discovery_timeout 60)
  rb_test_timeout(test_timeout 600)
  gtest_discover_tests(test_${module}
    TEST_PREFIX "${module}/"
    WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    DISCOVERY_TIMEOUT ${discovery_timeout}
    PROPERTIES TIMEOUT ${test_timeout})
endfunction()

# rb_test_timeout(VAR SECONDS): SECONDS times RANGEBAYES_TEST_TIMEOUT_FACTOR (the sanitizer presets raise it:
# their builds run the same tests several times slower), for every test's TIMEOUT.
function(rb_test_timeout var seconds)
  math(EXPR scaled "${seconds} * ${RANGEBAYES_TEST_TIMEOUT_FACTOR}")
  set(${var} ${scaled} PARENT_SCOPE)
endfunction()

function(rb_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  if(RANGEBAYES_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
