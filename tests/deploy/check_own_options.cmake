# The tool's command line is vigil's alone, on every target: the long options that libcobalt's
# automatic start-up would read before main() on a Cobalt build (--version, --help, --verbose,
# --quiet, --trace, --dump-config, --cpu-affinity, --main-prio, --print-buffer-size, and prefixes
# such as --vers) reach vigil's parser, which prints its own text or its own error. None of these
# starts Xenomai: the commands run here need no Cobalt core (docs/guide/xenomai-cobalt.md).
#   -DVIGIL=<vigil>
set(failures "")
# run(<expected exit: 0 or "fail">, <regex stdout+stderr must match>, args...)
function(run expect regex)
  execute_process(COMMAND ${VIGIL} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  set(all "${out}${err}")
  set(bad "")
  if(expect STREQUAL "0" AND NOT rc EQUAL 0)
    set(bad "exit ${rc}, expected 0")
  elseif(expect STREQUAL "fail" AND (rc EQUAL 0 OR NOT rc MATCHES "^[0-9]+$"))
    set(bad "exit ${rc}, expected a usage error")
  elseif(NOT all MATCHES "${regex}")
    set(bad "output does not match '${regex}'")
  elseif(all MATCHES "Xenomai|xenomai|Cobalt core|low_init")
    set(bad "output comes from Xenomai")
  endif()
  if(bad)
    string(APPEND failures "vigil ${ARGN}: ${bad}:\n${all}\n")
    set(failures "${failures}" PARENT_SCOPE)
  endif()
endfunction()

run(0 "^vigil [0-9]+\\.[0-9]+\\.[0-9]+" --version)
run(0 "^vigil [0-9]+\\.[0-9]+\\.[0-9]+" -V)
run(0 "vigil supervises real-time components.*demo.*check-config" --help)
run(0 "Run a supervised system" demo --help)
run(0 "Supervise the components of other processes" supervise --help)
# Xenomai's options and their prefixes are not vigil's: vigil's parser refuses each, alone (no
# command given) and after a command (naming it).
foreach(opt --vers --verbose --verb --quiet --silent --trace --dump-config --cpu-affinity=0
            --main-prio=1 --print-buffer-size=1024 --no-sanity)
  string(REGEX REPLACE "=.*" "" name "${opt}")
  run(fail "A subcommand is required" ${opt})
  run(fail "not expected: ${name}" check-config ${opt} deployment.yaml)
endforeach()
run(fail "not expected: --verbose" demo --verbose)
# A command that needs no real-time core runs to its end.
run(0 "name: " demo --print-config)

if(failures)
  message(FATAL_ERROR "${failures}")
endif()
message(STATUS "vigil's own options, and only those")
