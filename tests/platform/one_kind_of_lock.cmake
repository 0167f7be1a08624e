# Proves, over the built binaries of a Cobalt build, that no program mixes Cobalt and glibc
# synchronisation (docs/design/platform.md, "One kind of thread, one kind of lock"). Run with
# `cmake -P`; registered by tests/platform/CMakeLists.txt.
#
#   -DVIGIL_BINARY_LIST=<file> -DVIGIL_NM=<nm>
#       <file> names one executable per line. For each, the dynamic symbols it imports
#       (`nm -D --undefined-only`) are sorted into families, and the check fails, naming the
#       binary and the symbols, when one binary imports
#         - a Cobalt mutex (__wrap_pthread_mutex_* from libcobalt's --wrap list, or
#           __cobalt_pthread_mutex_*) together with a glibc condition variable (pthread_cond_*@GLIBC,
#           or libstdc++'s out-of-line std::condition_variable waits, which call glibc's) or a
#           glibc rwlock (pthread_rwlock_*@GLIBC: std::shared_mutex), or
#         - a Cobalt condition variable together with a glibc mutex.
#       A condition variable of one implementation waiting on a mutex of the other is undefined
#       behaviour, and Cobalt's mutex returns EPERM to threads Cobalt does not manage. It also
#       fails when a listed binary does not exist (build first) or when no binary imports any
#       Cobalt symbol at all (then this is not a Cobalt build and the check would prove nothing).
#   -DVIGIL_SELF_TEST=ON
#       checks the classification on made-up import lists: the mixes above are found, consistent
#       lists are not.
cmake_minimum_required(VERSION 3.25)

# Sets <prefix>_mixed (TRUE/FALSE) and <prefix>_detail (what was found) from a list of imported
# symbol names as nm prints them (name[@version]).
function(vigil_classify_imports symbols prefix)
  set(cobalt_mutex "")
  set(cobalt_cond "")
  set(glibc_mutex "")
  set(glibc_cond "")
  set(glibc_rwlock "")
  set(cobalt_any 0)
  foreach(sym IN LISTS symbols)
    if(sym MATCHES "^__(wrap|cobalt)_pthread_mutex_(lock|trylock|timedlock|unlock)")
      list(APPEND cobalt_mutex "${sym}")
    elseif(sym MATCHES "^__(wrap|cobalt)_pthread_cond_(wait|timedwait|signal|broadcast)")
      list(APPEND cobalt_cond "${sym}")
    elseif(sym MATCHES "^pthread_mutex_(lock|trylock|timedlock|clocklock|unlock)(@|$)")
      list(APPEND glibc_mutex "${sym}")
    elseif(sym MATCHES "^pthread_cond_[a-z]+(@|$)"
           OR sym MATCHES "^_ZNSt18condition_variable4wait"
           OR sym MATCHES "^_ZNSt3_V222condition_variable_any")
      list(APPEND glibc_cond "${sym}")
    elseif(sym MATCHES "^pthread_rwlock_[a-z]+(@|$)")
      list(APPEND glibc_rwlock "${sym}")
    endif()
    if(sym MATCHES "^__cobalt_|^__wrap_|^cobalt_|^xenomai_")
      set(cobalt_any 1)
    endif()
  endforeach()
  foreach(family cobalt_mutex cobalt_cond glibc_mutex glibc_cond glibc_rwlock)
    list(JOIN ${family} ", " ${family}_text)
  endforeach()
  set(mixed FALSE)
  set(detail "")
  if(cobalt_mutex AND (glibc_cond OR glibc_rwlock))
    set(mixed TRUE)
    string(APPEND detail "Cobalt mutex (${cobalt_mutex_text}) with glibc condition variable "
                         "(${glibc_cond_text}) / rwlock (${glibc_rwlock_text}) -- ")
  endif()
  if(cobalt_cond AND glibc_mutex)
    set(mixed TRUE)
    string(APPEND detail "Cobalt condition variable (${cobalt_cond_text}) with glibc mutex "
                         "(${glibc_mutex_text}) -- ")
  endif()
  list(LENGTH cobalt_mutex n_cm)
  list(LENGTH glibc_mutex n_gm)
  list(LENGTH glibc_cond n_gc)
  list(LENGTH glibc_rwlock n_gr)
  string(APPEND detail "mutex: ${n_cm} Cobalt, ${n_gm} glibc, glibc condvar: ${n_gc}, "
                       "glibc rwlock: ${n_gr}")
  set(${prefix}_mixed ${mixed} PARENT_SCOPE)
  set(${prefix}_detail "${detail}" PARENT_SCOPE)
  set(${prefix}_cobalt ${cobalt_any} PARENT_SCOPE)
endfunction()

if(VIGIL_SELF_TEST)
  set(failures "")
  macro(expect name expected)
    vigil_classify_imports("${ARGN}" r)
    if(NOT r_mixed STREQUAL "${expected}")
      list(APPEND failures "${name}: expected mixed=${expected}, got ${r_mixed} (${r_detail})")
    endif()
  endmacro()
  expect("wrapped mutex + glibc clockwait (std::condition_variable::wait_until)" TRUE
         __wrap_pthread_mutex_lock __wrap_pthread_mutex_unlock pthread_cond_clockwait@GLIBC_2.30)
  expect("wrapped mutex + glibc rwlock (std::shared_mutex)" TRUE
         __wrap_pthread_mutex_lock pthread_rwlock_rdlock@GLIBC_2.34)
  expect("wrapped mutex + libstdc++ condition_variable::wait" TRUE
         __wrap_pthread_mutex_lock
         _ZNSt18condition_variable4waitERSt11unique_lockISt5mutexE@GLIBCXX_3.4.11)
  expect("Cobalt condvar + glibc mutex" TRUE
         __cobalt_pthread_cond_wait pthread_mutex_lock@GLIBC_2.2.5)
  expect("glibc sync with explicit Cobalt services (vigil's model)" FALSE
         pthread_mutex_lock@GLIBC_2.2.5 pthread_cond_clockwait@GLIBC_2.30
         pthread_rwlock_wrlock@GLIBC_2.34 __cobalt_pthread_create __cobalt_sem_post
         __wrap_malloc __wrap_free)
  expect("Cobalt sync only" FALSE
         __cobalt_pthread_mutex_lock __cobalt_pthread_cond_wait __cobalt_pthread_mutex_unlock)
  if(failures)
    list(JOIN failures "\n  " text)
    message(FATAL_ERROR "one_kind_of_lock self-test failed:\n  ${text}")
  endif()
  message(STATUS "one_kind_of_lock self-test: 6 import lists classified as expected")
  return()
endif()

if(NOT VIGIL_BINARY_LIST OR NOT VIGIL_NM)
  message(FATAL_ERROR "usage: cmake -DVIGIL_BINARY_LIST=<file> -DVIGIL_NM=<nm> -P ${CMAKE_SCRIPT_MODE_FILE}")
endif()
file(STRINGS "${VIGIL_BINARY_LIST}" binaries)
set(failures "")
set(n_failures 0)
set(checked 0)
set(cobalt_binaries 0)
foreach(bin IN LISTS binaries)
  if(NOT EXISTS "${bin}")
    list(APPEND failures "${bin}: not built (build the whole tree before running this check)")
    math(EXPR n_failures "${n_failures} + 1")
    continue()
  endif()
  execute_process(COMMAND "${VIGIL_NM}" -D --undefined-only "${bin}"
                  OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    list(APPEND failures "${bin}: ${VIGIL_NM} failed: ${err}")
    math(EXPR n_failures "${n_failures} + 1")
    continue()
  endif()
  # Lines are "<spaces>U name[@version]" (or w/v for weak ones): keep the names.
  string(REGEX REPLACE "(^|\n)[ \t]*[A-Za-z][ \t]+" "\\1" out "${out}")
  string(STRIP "${out}" out)
  string(REPLACE "\n" ";" symbols "${out}")
  vigil_classify_imports("${symbols}" r)
  math(EXPR checked "${checked} + 1")
  if(r_cobalt)
    math(EXPR cobalt_binaries "${cobalt_binaries} + 1")
  endif()
  get_filename_component(name "${bin}" NAME)
  if(r_mixed)
    list(APPEND failures "${bin}: ${r_detail}")
    math(EXPR n_failures "${n_failures} + 1")
    message(STATUS "MIXED ${name}: ${r_detail}")
  else()
    message(STATUS "ok    ${name}: ${r_detail}")
  endif()
endforeach()
if(checked GREATER 0 AND cobalt_binaries EQUAL 0)
  list(APPEND failures "no binary imports a Cobalt symbol: not a Cobalt build, nothing proven")
  math(EXPR n_failures "${n_failures} + 1")
endif()
if(failures)
  list(JOIN failures "\n  " text)
  message(FATAL_ERROR "${n_failures} binaries mix Cobalt and glibc synchronisation or could not be "
                      "read (of ${checked} read):\n  ${text}")
endif()
message(STATUS "${checked} binaries read (${cobalt_binaries} linked with libcobalt): none mixes "
               "Cobalt and glibc mutexes, condition variables or rwlocks")
