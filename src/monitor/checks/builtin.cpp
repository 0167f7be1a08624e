#include "vigil/monitor/checks/builtin.hpp"

namespace vigil::monitor::checks {

void add_builtin_checks(CheckList& list) {
  list.add<InitializationCheck>();
  list.add<ExceptionCheck>();
  list.add<StarvationCheck>();
  list.add<OverrunCheck>();
  list.add<RealTimeCheck>();
  list.add<NotRealtimeCheck>();
  list.add<OverheadCheck>();
  list.add<DropsCheck>();
  list.add<LatchedCheck>();
}

}  // namespace vigil::monitor::checks
