// A ROS 2 /diagnostics subscriber on plain Cyclone DDS, in its own process: what a ROS 2 node
// with rmw_cyclonedds_cpp and default QoS does, with the types idlc generates from the same IDL
// as vigil's module (src/export/ros2/idl). Used by tests/export/ros2_diagnostics_test.cpp and by
// the `vigil demo --ros2` test.
//
//   vigil_ros2_listener DOMAIN COUNT TIMEOUT_S [MIN_STATUSES [GID_SIZE]]
//
// Prints each sample as one JSON line (exporter::to_diagnostics_json, the same document the
// tests build from what they published) and exits 0 once it has printed COUNT samples with at
// least MIN_STATUSES statuses (default 0; smaller ones are printed but not counted), 1 when
// TIMEOUT_S passes first, 2 on a DDS error. The DDS
// configuration comes from CYCLONEDDS_URI (the tests restrict it to loopback).
//
// With GID_SIZE (16: Iron and later, 24: Humble), it also reads `ros_discovery_info` as a ROS 2
// node does (rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_ of that layout; reliable,
// transient local, keep all) and, once it has a sample of each, prints one more line:
//   {"ros_discovery_info":{"gid":HEX,"nodes":[{"namespace":..,"name":..,"readers":[HEX..],
//    "writers":[HEX..]}]},"publisher":{"gid":HEX,"participant_gid":HEX}}
// where "publisher" holds the graph ids of the /diagnostics writer as rmw_cyclonedds_cpp derives
// them from DDS discovery (the DCPSPublication data of the writer of a received sample: its key
// and its participant's, GUID bytes then zeros to GID_SIZE), for the test to compare.
#include <dds/dds.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "diagnostic_msgs/msg/dds_/DiagnosticArray_.h"
#include "humble/rmw_dds_common/msg/dds_/ParticipantEntitiesInfo_.h"
#include "rmw_dds_common/msg/dds_/ParticipantEntitiesInfo_.h"
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

std::string hex(const unsigned char* p, std::size_t n) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s = "\"";
  for (std::size_t i = 0; i < n; ++i) {
    s += kDigits[p[i] >> 4];
    s += kDigits[p[i] & 15];
  }
  return s + "\"";
}

std::string quoted(const char* s) {
  std::string out = "\"";
  for (const char* c = s; *c != '\0'; ++c) {
    if (*c == '"' || *c == '\\') out += '\\';
    out += *c;
  }
  return out + "\"";
}

// A GUID as rmw_cyclonedds_cpp turns it into a graph id: the 16 bytes, then zeros.
std::string gid_of(const dds_guid_t& g, std::size_t size) {
  unsigned char b[24] = {};
  std::copy(std::begin(g.v), std::end(g.v), b);
  return hex(b, size);
}

// A ParticipantEntitiesInfo_ of either layout as JSON.
template <class Info>
std::string discovery_json(const Info& info) {
  std::string s = "{\"gid\":" + hex(info.gid.data, sizeof info.gid.data) + ",\"nodes\":[";
  for (std::uint32_t i = 0; i < info.node_entities_info_seq._length; ++i) {
    const auto& n = info.node_entities_info_seq._buffer[i];
    if (i > 0) s += ',';
    s += "{\"namespace\":" + quoted(n.node_namespace) + ",\"name\":" + quoted(n.node_name) +
         ",\"readers\":[";
    for (std::uint32_t k = 0; k < n.reader_gid_seq._length; ++k) {
      if (k > 0) s += ',';
      s += hex(n.reader_gid_seq._buffer[k].data, sizeof n.reader_gid_seq._buffer[k].data);
    }
    s += "],\"writers\":[";
    for (std::uint32_t k = 0; k < n.writer_gid_seq._length; ++k) {
      if (k > 0) s += ',';
      s += hex(n.writer_gid_seq._buffer[k].data, sizeof n.writer_gid_seq._buffer[k].data);
    }
    s += "]}";
  }
  return s + "]}";
}

// The humble layout under its ROS 2 type name (see src/export/ros2/idl/humble).
const dds_topic_descriptor_t* humble_descriptor() {
  static const dds_topic_descriptor_t desc = [] {
    dds_topic_descriptor_t d = humble_rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc;
    d.m_typename = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";
    return d;
  }();
  return &desc;
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
  const int gid_size = argc > 5 ? std::atoi(argv[5]) : 0;
  if (gid_size != 0 && gid_size != 16 && gid_size != 24) {
    std::fprintf(stderr, "GID_SIZE must be 16 or 24\n");
    return 2;
  }

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
  // ros_discovery_info as rmw_cyclonedds_cpp's subscription reads it.
  dds_entity_t discovery = 0;
  if (gid_size != 0) {
    dds_qos_t* dq = dds_create_qos();
    dds_qset_reliability(dq, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_durability(dq, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(dq, DDS_HISTORY_KEEP_ALL, 0);
    const dds_entity_t dt =
        dds_create_topic(participant,
                         gid_size == 24 ? humble_descriptor()
                                        : &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                         "ros_discovery_info", dq, nullptr);
    discovery = dt < 0 ? dt : dds_create_reader(participant, dt, dq, nullptr);
    dds_delete_qos(dq);
    if (discovery < 0) {
      std::fprintf(stderr, "ros_discovery_info reader: %s\n", dds_strretcode(discovery));
      (void)dds_delete(participant);
      return 2;
    }
  }
  std::fprintf(stderr, "listening on rt/diagnostics in domain %u\n", static_cast<unsigned>(domain));

  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int received = 0;
  std::string publisher;       // the /diagnostics writer's graph ids, as JSON
  std::string discovery_info;  // the latest ros_discovery_info sample, as JSON
  bool discovery_said = gid_size == 0;
  while ((received < count || !discovery_said) && std::chrono::steady_clock::now() < end) {
    if (gid_size != 0) {
      void* ds[1] = {nullptr};
      dds_sample_info_t di[1];
      const dds_return_t dn = dds_take(discovery, ds, di, 1, 1);
      if (dn > 0 && di[0].valid_data) {
        discovery_info =
            gid_size == 24
                ? discovery_json(
                      *static_cast<const humble_rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(
                          ds[0]))
                : discovery_json(
                      *static_cast<const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(ds[0]));
      }
      if (dn > 0) (void)dds_return_loan(discovery, ds, dn);
      if (!discovery_said && !discovery_info.empty() && !publisher.empty()) {
        std::printf("{\"ros_discovery_info\":%s,\"publisher\":%s}\n", discovery_info.c_str(),
                    publisher.c_str());
        std::fflush(stdout);
        discovery_said = true;
      }
    }
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
    if (info[0].valid_data && gid_size != 0 && publisher.empty()) {
      dds_builtintopic_endpoint_t* w =
          dds_get_matched_publication_data(reader, info[0].publication_handle);
      if (w != nullptr) {
        const auto size = static_cast<std::size_t>(gid_size);
        publisher = "{\"gid\":" + gid_of(w->key, size) +
                    ",\"participant_gid\":" + gid_of(w->participant_key, size) + "}";
        dds_builtintopic_free_endpoint(w);
      }
    }
    if (info[0].valid_data && received < count) {  // COUNT lines, however long discovery takes
      const auto* a = static_cast<const diagnostic_msgs_msg_dds__DiagnosticArray_*>(samples[0]);
      std::printf("%s\n", vigil::exporter::to_diagnostics_json(convert(*a)).c_str());
      std::fflush(stdout);
      if (a->status._length >= min_statuses) ++received;
    }
    (void)dds_return_loan(reader, samples, n);
  }
  (void)dds_delete(participant);
  return received >= count && discovery_said ? 0 : 1;
}
