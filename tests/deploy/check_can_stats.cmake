# `vigil can-stats` on the real J1939 capture reproduces the independent figures of
# ../shared/data/can/README.md exactly.
# The capture is outside the repository: without it the test is Skipped (the message matches
# the test's SKIP_REGULAR_EXPRESSION), not passed.
if(NOT EXISTS ${LOG})
  get_filename_component(name ${LOG} NAME)
  message("skipped: ../shared/data/can/${name} absent (looked for ${LOG})")
  return()
endif()
execute_process(COMMAND ${VIGIL} can-stats ${LOG} --node-map j1939
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "vigil can-stats exited with ${rc}")
endif()
set(failures "")
foreach(expect
    "19535 frames, 1648583717.428998 to 1648586979.907437"
    "(19535 frames, 23 ids, 3 nodes"
    "0CF00400  0x00  PGN 61444 (0xF004)  Rx     2686     2686      18.659      20.013       21.436"
    "18FEF121  0x21  PGN 65265 (0xFEF1)  Rx     5235     5235      10.538     100.007  2624577.524")
  string(FIND "${out}" "${expect}" at)
  if(at EQUAL -1)
    string(APPEND failures "missing: ${expect}\n")
  endif()
endforeach()
if(failures)
  message(FATAL_ERROR "${failures}")
endif()
