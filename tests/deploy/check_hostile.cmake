# `vigil check-config` (deployment and thresholds) and `vigil can-stats -c` on hostile files
# (tests/config/data/hostile: a lone ',', an alias bomb, a recursive alias, 1,000 levels of
# nesting): each exits 1, promptly (the test's TIMEOUT), with an error naming file:line:col.
file(GLOB files ${DATA}/*.yaml)
set(failures "")
foreach(f ${files})
  foreach(cmd "check-config;${f}" "check-config;--kind;thresholds;${f}"
              "check-config;--kind;deployment;${f}" "can-stats;-c;${f};${LOG}")
    execute_process(COMMAND ${VIGIL} ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                    ERROR_VARIABLE err TIMEOUT 20)
    string(FIND "${err}" "${f}:" at)
    if(NOT rc EQUAL 1 OR NOT at EQUAL 0 OR NOT err MATCHES "^[^\n]*:[0-9]+:[0-9]+: [a-z]")
      string(APPEND failures "vigil ${cmd}: expected exit 1 and FILE:LINE:COL: message, got "
                             "${rc}: ${out}${err}\n")
    endif()
  endforeach()
endforeach()
list(LENGTH files n)
if(failures OR n LESS 4)
  message(FATAL_ERROR "${n} files\n${failures}")
endif()
message(STATUS "${n} hostile files refused with file:line:col by check-config and can-stats -c")
