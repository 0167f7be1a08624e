# Says whether a directory of shared data (outside the repository) is present. Absent: prints
# "skipped: NAME absent", which the test's SKIP_REGULAR_EXPRESSION turns into Skipped.
if(EXISTS "${DIR}")
  message("${NAME} present (${DIR}): the tests that read it run")
else()
  message("skipped: ${NAME} absent (looked for ${DIR}); the tests that read it are skipped")
endif()
