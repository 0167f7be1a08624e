# `vigil supervise --health FILE`: a bad section fails at once with its file, line and column; a
# good one is supervised (a component it names that never joins is reported, as an event, when its
# start-up grace period ends).
set(dir ${DATA}/supervise_health)
string(RANDOM LENGTH 8 ALPHABET abcdefghijklmnopqrstuvwxyz0123456789 suffix)
set(NAME cli-health-${suffix})  # its own supervisor name: parallel runs never meet
execute_process(COMMAND ${VIGIL} supervise --name ${NAME} --health ${dir}/bad.yaml --duration 1
                        --no-live --color never
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${err}" "bad.yaml:3:" at)
string(FIND "${err}" "min (5000 us) is above max (1000 us)" why)
if(NOT rc EQUAL 1 OR at EQUAL -1 OR why EQUAL -1)
  message(FATAL_ERROR "bad.yaml: expected exit 1 naming line 3 and the cause, got ${rc}:\n${out}${err}")
endif()
execute_process(COMMAND ${VIGIL} supervise --name ${NAME} --health ${dir}/good.yaml --duration 1.5
                        --no-live --color never
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${out}" "alive_supervision" kind)
string(FIND "${out}" "ghost has not started within its start-up grace period" text)
string(FIND "${out}" "supervision ghost_alive" unit)
if(NOT rc EQUAL 0 OR kind EQUAL -1 OR text EQUAL -1 OR unit EQUAL -1)
  message(FATAL_ERROR "good.yaml: expected the never-started event and the unit, got ${rc}:\n${out}${err}")
endif()
# `--diagnosis FILE`: a cycle is refused with its place; an aggregate is reported, its member named
# as its root cause.
execute_process(COMMAND ${VIGIL} supervise --name ${NAME} --diagnosis ${dir}/diagnosis_bad.yaml
                        --duration 1 --no-live --color never
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${err}" "diagnosis_bad.yaml:3:" at)
string(FIND "${err}" "the dependencies form a cycle" why)
if(NOT rc EQUAL 1 OR at EQUAL -1 OR why EQUAL -1)
  message(FATAL_ERROR "diagnosis_bad.yaml: expected exit 1 naming the cycle, got ${rc}:\n${out}${err}")
endif()
execute_process(COMMAND ${VIGIL} supervise --name ${NAME} --health ${dir}/good.yaml
                        --diagnosis ${dir}/diagnosis_good.yaml --duration 1.5 --no-live --color never
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${out}" "ghosts" aggregate)
string(FIND "${out}" "ROOT CAUSE" root)
if(NOT rc EQUAL 0 OR aggregate EQUAL -1 OR root EQUAL -1)
  message(FATAL_ERROR "diagnosis_good.yaml: expected the aggregate and a root cause, got ${rc}:\n${out}${err}")
endif()
message(STATUS "vigil supervise --health, --diagnosis: bad sections refused, good ones applied")
