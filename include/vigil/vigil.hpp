#pragma once
/// @file
/// Umbrella header: everything a component author and an integrator need.
/// Library code includes the precise headers instead.

#include "vigil/config.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"
#include "vigil/platform/clock.hpp"
#include "vigil/platform/memory.hpp"
#include "vigil/platform/rt_loss.hpp"
#include "vigil/platform/thread.hpp"
#include "vigil/platform/thread_stats.hpp"
#include "vigil/version.hpp"
