// A ROS 2 /diagnostics subscriber on plain Cyclone DDS, in its own process: what a ROS 2 node
// with rmw_cyclonedds_cpp and default QoS does, with the types idlc generates from the same IDL
// as vigil's module (src/export/ros2/idl). Used by tests/export/ros2_diagnostics_test.cpp and by
// the `vigil demo --ros2` test.
//
//   vigil_ros2_listener DOMAIN COUNT TIMEOUT_S [MIN_STATUSES]
//
// Prints each sample as one JSON line (exporter::to_diagnostics_json, the same document the
// tests build from what they published) and exits 0 once it has printed COUNT samples with at
// least MIN_STATUSES statuses (default 0; smaller ones are printed but not counted), 1 when
// TIMEOUT_S passes first, 2 on a DDS error. The DDS
// configuration comes from CYCLONEDDS_URI (the tests restrict it to loopback).
#include <dds/dds.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "diagnostic_msgs/msg/dds_/DiagnosticArray_.h"
#include "vigil/export/diagnostics.hpp"

namespace {

std::string text(const char* s) { return s != nullptr ? std::string(s) : std::string(); }

vigil::exporter::DiagnosticArrayMessage convert(
    const diagnostic_msgs_msg_dds__DiagnosticArray_& a) {
  vigil::exporter::DiagnosticArrayMessage m;
  m.sec = a.header.stamp.sec;
  m.nanosec = a.header.stamp.nanosec;
  m.frame_id = text(a.header.frame_id);
  for (std::uint32_t i = 0; i < a.status._length; ++i) {
    const auto& s = a.status._buffer[i];
    vigil::exporter::DiagnosticStatusMessage d;
    d.level = s.level;
    d.name = text(s.name);
    d.message = text(s.message);
    d.hardware_id = text(s.hardware_id);
    for (std::uint32_t k = 0; k < s.values._length; ++k) {
      d.values.push_back({text(s.values._buffer[k].key), text(s.values._buffer[k].value)});
    }
    m.status.push_back(std::move(d));
  }
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s DOMAIN COUNT TIMEOUT_S [MIN_STATUSES]\n", argv[0]);
    return 2;
  }
  const auto domain = static_cast<dds_domainid_t>(std::atoi(argv[1]));
  const int count = std::atoi(argv[2]);
  const double timeout_s = std::atof(argv[3]);
  const std::uint32_t min_statuses = argc > 4 ? static_cast<std::uint32_t>(std::atoi(argv[4])) : 0;

  const dds_entity_t participant = dds_create_participant(domain, nullptr, nullptr);
  if (participant < 0) {
    std::fprintf(stderr, "dds_create_participant: %s\n", dds_strretcode(participant));
    return 2;
  }
  // rclcpp's default QoS profile, as rmw_cyclonedds_cpp sets it on a reader.
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 10);
  const dds_entity_t topic = dds_create_topic(
      participant, &diagnostic_msgs_msg_dds__DiagnosticArray__desc, "rt/diagnostics", q, nullptr);
  const dds_entity_t reader = topic < 0 ? topic : dds_create_reader(participant, topic, q, nullptr);
  dds_delete_qos(q);
  if (reader < 0) {
    std::fprintf(stderr, "dds_create_reader: %s\n", dds_strretcode(reader));
    (void)dds_delete(participant);
    return 2;
  }
  std::fprintf(stderr, "listening on rt/diagnostics in domain %u\n", static_cast<unsigned>(domain));

  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int received = 0;
  while (received < count && std::chrono::steady_clock::now() < end) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info[1];
    const dds_return_t n = dds_take(reader, samples, info, 1, 1);
    if (n < 0) {
      std::fprintf(stderr, "dds_take: %s\n", dds_strretcode(n));
      break;
    }
    if (n == 0) {
      dds_sleepfor(DDS_MSECS(5));
      continue;
    }
    if (info[0].valid_data) {
      const auto* a = static_cast<const diagnostic_msgs_msg_dds__DiagnosticArray_*>(samples[0]);
      std::printf("%s\n", vigil::exporter::to_diagnostics_json(convert(*a)).c_str());
      std::fflush(stdout);
      if (a->status._length >= min_statuses) ++received;
    }
    (void)dds_return_loan(reader, samples, n);
  }
  (void)dds_delete(participant);
  return received >= count ? 0 : 1;
}
