// The probes of benches/lttng/vigil_bench_tp.h, compiled once (lttng-ust's rule: exactly one
// translation unit defines LTTNG_UST_TRACEPOINT_CREATE_PROBES and LTTNG_UST_TRACEPOINT_DEFINE).
#define LTTNG_UST_TRACEPOINT_CREATE_PROBES
#define LTTNG_UST_TRACEPOINT_DEFINE
#include "lttng/vigil_bench_tp.h"
