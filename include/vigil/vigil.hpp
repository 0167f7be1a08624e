#pragma once
/// @file
/// Umbrella header: everything a component author and an integrator need.
/// Library code includes the precise headers instead.

#include "vigil/bus/port.hpp"
#include "vigil/bus/registry.hpp"
#include "vigil/config.hpp"
#include "vigil/error.hpp"
#include "vigil/exec/manual_activity.hpp"
#include "vigil/exec/periodic_activity.hpp"
#include "vigil/exec/triggered_activity.hpp"
#include "vigil/expected.hpp"
#include "vigil/export/json_report.hpp"
#include "vigil/export/text_report.hpp"
#include "vigil/monitor/monitor.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/platform/process.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/supervisor/supervisor.hpp"
#include "vigil/task/component_supervisor.hpp"
#include "vigil/task/default_registry.hpp"
#include "vigil/task/messages.hpp"
#include "vigil/task/task.hpp"
#include "vigil/version.hpp"
