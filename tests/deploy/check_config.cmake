# `vigil check-config` on good and bad files: good ones pass; each bad one fails with the exact
# file:line:col and message written in its sidecar file bad_NAME.expect (@FILE@ = the file).
file(GLOB good ${DATA}/good_*.yaml)
file(GLOB bad ${DATA}/bad_*.yaml)
set(failures "")
foreach(f ${good})
  execute_process(COMMAND ${VIGIL} check-config ${f} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    string(APPEND failures "${f}: expected OK, got ${rc}: ${out}${err}\n")
  endif()
endforeach()
foreach(f ${bad})
  string(REGEX REPLACE "\\.yaml$" ".expect" expect_file "${f}")
  file(READ ${expect_file} expect)  # not file(STRINGS): messages contain ';'
  string(STRIP "${expect}" expect)
  string(REPLACE "@FILE@" "${f}" expect "${expect}")
  execute_process(COMMAND ${VIGIL} check-config ${f} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  string(FIND "${err}" "${expect}" at)  # quoted: never split at ';' 
  if(rc EQUAL 0 OR at EQUAL -1)
    string(APPEND failures "${f}: expected failure with '${expect}', got ${rc}: ${out}${err}\n")
  endif()
endforeach()
list(LENGTH good ng)
list(LENGTH bad nb)
if(failures)
  message(FATAL_ERROR "${failures}")
endif()
message(STATUS "check-config: ${ng} good and ${nb} bad files as expected")
