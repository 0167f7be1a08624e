#pragma once
// Checks that two flight-recorder cycles are the same, field by field (each field its own CHECK,
// so that a failure names the field).
#include <catch2/catch.hpp>

#include "vigil/supervisor/flight_recorder.hpp"

namespace vigil::test {

inline void check_same(const supervisor::CycleRecord& a, const supervisor::CycleRecord& b) {
  CHECK(a.cycle == b.cycle);
  CHECK(a.release_ns == b.release_ns);
  CHECK(a.start_ns == b.start_ns);
  CHECK(a.end_ns == b.end_ns);
  CHECK(a.overhead_ns == b.overhead_ns);
  CHECK(a.missed_before == b.missed_before);
  CHECK(a.flags == b.flags);
  CHECK(a.state == b.state);
}

}  // namespace vigil::test
