// LTTng-UST tracepoint provider of the benchmarks (benches/ only; vigil itself has no tracing
// dependency): the two tracepoints a tracing user puts around a loop's body, a cycle's start and
// its end, each carrying the cycle number. The timestamp is LTTng's own (every event has one).
//
// This header is read several times by lttng-ust's macros (it must not have an include guard of
// its own beyond LTTNG_UST's pattern below).
#undef LTTNG_UST_TRACEPOINT_PROVIDER
#define LTTNG_UST_TRACEPOINT_PROVIDER vigil_bench

#undef LTTNG_UST_TRACEPOINT_INCLUDE
#define LTTNG_UST_TRACEPOINT_INCLUDE "lttng/vigil_bench_tp.h"

#if !defined(VIGIL_BENCH_TP_H) || defined(LTTNG_UST_TRACEPOINT_HEADER_MULTI_READ)
#define VIGIL_BENCH_TP_H

#include <lttng/tracepoint.h>

LTTNG_UST_TRACEPOINT_EVENT(vigil_bench, cycle_start,
                           LTTNG_UST_TP_ARGS(unsigned long, cycle),
                           LTTNG_UST_TP_FIELDS(lttng_ust_field_integer(unsigned long, cycle, cycle)))

LTTNG_UST_TRACEPOINT_EVENT(vigil_bench, cycle_end,
                           LTTNG_UST_TP_ARGS(unsigned long, cycle),
                           LTTNG_UST_TP_FIELDS(lttng_ust_field_integer(unsigned long, cycle, cycle)))

#endif  // VIGIL_BENCH_TP_H

#include <lttng/tracepoint-event.h>
