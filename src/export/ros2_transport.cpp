// The loadable module `vigil_ros2` (ros2_transport.hpp): a Cyclone DDS participant with one
// writer of `diagnostic_msgs::msg::dds_::DiagnosticArray_` on the topic `rt/diagnostics`, with
// the QoS and the encoding a ROS 2 subscriber with default settings matches, and the writer of
// `ros_discovery_info` that tells ROS 2 which node that writer belongs to
// (docs/design/ros2-diagnostics.md gives the sources of each choice).
#include "ros2_transport.hpp"

#include <dds/dds.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

#include "diagnostic_msgs/msg/dds_/DiagnosticArray_.h"
#include "humble/rmw_dds_common/msg/dds_/ParticipantEntitiesInfo_.h"
#include "rmw_dds_common/msg/dds_/ParticipantEntitiesInfo_.h"
#include "vigil/version.hpp"

namespace vigil::exporter::detail {
namespace {

// Cyclone reads the sample only: the strings are borrowed from the message, never freed.
char* borrow(const std::string& s) { return const_cast<char*>(s.c_str()); }

// The QoS of rclcpp's default profile (rmw_qos_profile_default): reliable, volatile, keep last
// 10, as rmw_cyclonedds_cpp's create_readwrite_qos sets it (with auto-dispose off), and the one
// data representation its sertype allows, XCDR1. The reliable writer blocks at most 100 ms (rmw
// says forever; with keep-last history a write never waits for room anyway).
dds_qos_t* ros_default_qos() {
  dds_qos_t* q = dds_create_qos();
  dds_qset_writer_data_lifecycle(q, false);
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 10);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(q, 1, &xcdr1);
  return q;
}

// The QoS rmw gives its `ros_discovery_info` writer: the default profile made reliable,
// transient local, keep last 1 (rmw_cyclonedds_cpp's rmw_context_impl_s::init; rmw_fastrtps
// likewise), so a ROS 2 node that starts after vigil still gets the latest sample.
dds_qos_t* discovery_qos() {
  dds_qos_t* q = ros_default_qos();
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  return q;
}

// The DDS type name of rmw_dds_common/msg/ParticipantEntitiesInfo, whatever the distribution.
constexpr const char* kParticipantEntitiesInfoType =
    "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";

// Humble's layout (24-byte Gid) comes from IDL under an extra module `humble` (so that its C
// names differ from Iron's); on the wire it must carry the ROS 2 type name, without `humble::`.
// The descriptor is copied with that name: nothing else in it names the type (idlc -t: no
// type information).
const dds_topic_descriptor_t* humble_participant_entities_info() {
  static const dds_topic_descriptor_t desc = [] {
    dds_topic_descriptor_t d = humble_rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc;
    d.m_typename = kParticipantEntitiesInfoType;
    return d;
  }();
  return &desc;
}

// A graph id as rmw computes it from a DDS entity (rmw_cyclonedds_cpp's get_entity_gid, which
// rmw_fastrtps matches with the GUID's prefix and entity id): the entity's 16-byte GUID in wire
// order (dds_get_guid), then zeros up to `size` bytes.
std::string entity_gid(dds_entity_t entity, int size) {
  dds_guid_t guid{};
  if (dds_get_guid(entity, &guid) != DDS_RETCODE_OK) return {};
  std::string gid(static_cast<std::size_t>(size), '\0');
  std::memcpy(gid.data(), guid.v, std::min(sizeof guid.v, gid.size()));
  return gid;
}

// Bounded strings (string<256>) are char arrays in idlc's C; the output checked the lengths.
template <std::size_t N>
void copy_bounded(char (&to)[N], const std::string& from) {
  const std::size_t n = std::min(from.size(), N - 1);
  std::memcpy(to, from.data(), n);
  to[n] = '\0';
}

// One ParticipantEntitiesInfo_ (of either layout) naming one node with one writer and no reader.
template <class Info, class Gid, class Node>
void fill_announcement(Info& info, Gid& writer, Node& node, const Ros2TransportConfig& config,
                       const Ros2NodeAnnouncement& a) {
  static_assert(sizeof info.gid.data == sizeof writer.data);
  std::memcpy(info.gid.data, a.participant_gid.data(), sizeof info.gid.data);
  std::memcpy(writer.data, a.writer_gid.data(), sizeof writer.data);
  copy_bounded(node.node_namespace, config.node_namespace);
  copy_bounded(node.node_name, config.node_name);
  node.reader_gid_seq._maximum = node.reader_gid_seq._length = 0;
  node.reader_gid_seq._buffer = nullptr;
  node.reader_gid_seq._release = false;
  node.writer_gid_seq._maximum = node.writer_gid_seq._length = 1;
  node.writer_gid_seq._buffer = &writer;
  node.writer_gid_seq._release = false;
  info.node_entities_info_seq._maximum = info.node_entities_info_seq._length = 1;
  info.node_entities_info_seq._buffer = &node;
  info.node_entities_info_seq._release = false;
}

// Cyclone's threads (gc, dq.builtins, dq.user, tev, recv, recvMC, recvUC) get glibc's default
// stack, the stack limit (8 MiB), unless the configuration says otherwise, and under mlockall (a
// deployment's lock_memory) every byte of it is resident: 56 MiB for the seven threads. 512 KiB
// each is plenty for them. The extra receive threads (recvMC, recvUC) take no configured stack,
// so one receive thread serves every socket: ample for a topic written once a second.
constexpr const char* kThreadStacks =
    "<CycloneDDS><Domain id=\"any\"><Threads>"
    "<Thread name=\"gc\"><StackSize>512KiB</StackSize></Thread>"
    "<Thread name=\"dq.builtins\"><StackSize>512KiB</StackSize></Thread>"
    "<Thread name=\"dq.user\"><StackSize>512KiB</StackSize></Thread>"
    "<Thread name=\"tev\"><StackSize>512KiB</StackSize></Thread>"
    "<Thread name=\"recv\"><StackSize>512KiB</StackSize></Thread>"
    "<Thread name=\"lease\"><StackSize>512KiB</StackSize></Thread>"
    "</Threads><Internal><MultipleReceiveThreads>false</MultipleReceiveThreads></Internal>"
    "</Domain></CycloneDDS>";

class CycloneTransport final : public Ros2Transport {
 public:
  CycloneTransport(const CycloneTransport&) = delete;
  CycloneTransport& operator=(const CycloneTransport&) = delete;

  static Ros2Transport* create(const Ros2TransportConfig& config, std::string* error) {
    auto* t = new CycloneTransport();
    std::string why = t->open(config);
    if (why.empty()) return t;
    delete t;
    if (error != nullptr) *error = std::move(why);
    return nullptr;
  }

  ~CycloneTransport() override {
    // Deleting the domain (or the participant) deletes the topic and the writer; a reliable
    // writer lingers until its readers have acknowledged what it wrote (Cyclone's
    // WriterLingerDuration).
    if (domain_ > 0) {
      (void)dds_delete(domain_);
    } else if (participant_ > 0) {
      (void)dds_delete(participant_);
    }
  }

  std::string publish(const DiagnosticArrayMessage& m) override {
    std::lock_guard lock(mutex_);
    std::size_t pairs = 0;
    for (const auto& s : m.status) pairs += s.values.size();
    statuses_.resize(m.status.size());
    values_.resize(pairs);
    std::size_t next = 0;
    for (std::size_t i = 0; i < m.status.size(); ++i) {
      const DiagnosticStatusMessage& s = m.status[i];
      diagnostic_msgs_msg_dds__DiagnosticStatus_& d = statuses_[i];
      d.level = s.level;
      d.name = borrow(s.name);
      d.message = borrow(s.message);
      d.hardware_id = borrow(s.hardware_id);
      d.values._maximum = d.values._length = static_cast<std::uint32_t>(s.values.size());
      d.values._buffer = values_.data() + next;
      d.values._release = false;
      for (const DiagnosticKeyValue& kv : s.values) {
        values_[next].key = borrow(kv.key);
        values_[next].value = borrow(kv.value);
        ++next;
      }
    }
    diagnostic_msgs_msg_dds__DiagnosticArray_ sample{};
    sample.header.stamp.sec = m.sec;
    sample.header.stamp.nanosec = m.nanosec;
    sample.header.frame_id = borrow(m.frame_id);
    sample.status._maximum = sample.status._length = static_cast<std::uint32_t>(statuses_.size());
    sample.status._buffer = statuses_.data();
    sample.status._release = false;
    const dds_return_t rc = dds_write(writer_, &sample);
    return rc == DDS_RETCODE_OK ? std::string() : dds_error("dds_write", rc);
  }

  [[nodiscard]] std::uint32_t matched() const override {
    dds_publication_matched_status_t st{};
    if (dds_get_publication_matched_status(writer_, &st) != DDS_RETCODE_OK) return 0;
    return st.current_count;
  }

  [[nodiscard]] Ros2NodeAnnouncement node() const override { return node_; }

 private:
  CycloneTransport() = default;

  std::string open(const Ros2TransportConfig& config) {
    // The configuration: the thread stacks below, then the user's (config.config, else
    // CYCLONEDDS_URI), which may override them; Cyclone merges a comma-separated list.
    std::string merged = kThreadStacks;
    const char* env = std::getenv("CYCLONEDDS_URI");
    const std::string user = !config.config.empty() ? config.config
                             : env != nullptr       ? std::string(env)
                                                    : std::string();
    if (!user.empty()) merged += "," + user;
    domain_ = dds_create_domain(config.domain_id, merged.c_str());
    if (domain_ == DDS_RETCODE_PRECONDITION_NOT_MET) {
      domain_ = 0;  // another part of the process made this domain: join it as it is
    } else if (domain_ < 0) {
      return dds_error(config.config.empty() && env != nullptr
                           ? "cannot create the DDS domain with CYCLONEDDS_URI"
                           : "cannot create the DDS domain with this configuration",
                       domain_);
    }
    dds_qos_t* pq = dds_create_qos();
    // What rmw_cyclonedds_cpp puts in a participant's user data: the security enclave.
    static constexpr char kEnclave[] = "enclave=/;";
    dds_qset_userdata(pq, kEnclave, sizeof kEnclave - 1);
    participant_ = dds_create_participant(config.domain_id, pq, nullptr);
    dds_delete_qos(pq);
    if (participant_ < 0) return dds_error("cannot create the DDS participant", participant_);
    dds_qos_t* q = ros_default_qos();
    topic_ = dds_create_topic(participant_, &diagnostic_msgs_msg_dds__DiagnosticArray__desc,
                              config.topic.c_str(), q, nullptr);
    if (topic_ < 0) {
      dds_delete_qos(q);
      return dds_error("cannot create the DDS topic " + config.topic, topic_);
    }
    writer_ = dds_create_writer(participant_, topic_, q, nullptr);
    dds_delete_qos(q);
    if (writer_ < 0) return dds_error("cannot create the DDS writer", writer_);
    return config.node_name.empty() ? std::string() : announce(config);
  }

  // ros_discovery_info: this participant holds one ROS 2 node, whose one writer is /diagnostics'.
  // Written once; rmw writes again only when a node's entities change, and vigil's never do.
  std::string announce(const Ros2TransportConfig& config) {
    if (config.gid_size != 16 && config.gid_size != 24) {
      return "a ROS 2 graph id has 16 or 24 bytes, not " + std::to_string(config.gid_size);
    }
    Ros2NodeAnnouncement a{entity_gid(participant_, config.gid_size),
                           entity_gid(writer_, config.gid_size)};
    if (a.participant_gid.empty() || a.writer_gid.empty()) {
      return "cannot read the GUIDs of the DDS participant and writer";
    }
    const bool humble = config.gid_size == 24;
    dds_qos_t* q = discovery_qos();
    discovery_topic_ =
        dds_create_topic(participant_,
                         humble ? humble_participant_entities_info()
                                : &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                         "ros_discovery_info", q, nullptr);
    if (discovery_topic_ < 0) {
      dds_delete_qos(q);
      return dds_error("cannot create the DDS topic ros_discovery_info", discovery_topic_);
    }
    discovery_writer_ = dds_create_writer(participant_, discovery_topic_, q, nullptr);
    dds_delete_qos(q);
    if (discovery_writer_ < 0) {
      return dds_error("cannot create the ros_discovery_info writer", discovery_writer_);
    }
    dds_return_t rc = DDS_RETCODE_OK;
    if (humble) {
      humble_rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ info{};
      humble_rmw_dds_common_msg_dds__Gid_ writer{};
      humble_rmw_dds_common_msg_dds__NodeEntitiesInfo_ node{};
      fill_announcement(info, writer, node, config, a);
      rc = dds_write(discovery_writer_, &info);
    } else {
      rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ info{};
      rmw_dds_common_msg_dds__Gid_ writer{};
      rmw_dds_common_msg_dds__NodeEntitiesInfo_ node{};
      fill_announcement(info, writer, node, config, a);
      rc = dds_write(discovery_writer_, &info);
    }
    if (rc != DDS_RETCODE_OK) return dds_error("cannot write ros_discovery_info", rc);
    node_ = std::move(a);
    return {};
  }

  static std::string dds_error(const std::string& what, dds_return_t rc) {
    return what + ": " + dds_strretcode(rc);
  }

  dds_entity_t domain_ = 0;
  dds_entity_t participant_ = 0;
  dds_entity_t topic_ = 0;
  dds_entity_t writer_ = 0;
  dds_entity_t discovery_topic_ = 0;
  dds_entity_t discovery_writer_ = 0;
  Ros2NodeAnnouncement node_;  // set once by open()
  std::mutex mutex_;           // guards the buffers below: publish() comes from two threads
  std::vector<diagnostic_msgs_msg_dds__DiagnosticStatus_> statuses_;
  std::vector<diagnostic_msgs_msg_dds__KeyValue_> values_;
};

}  // namespace
}  // namespace vigil::exporter::detail

extern "C" {

__attribute__((visibility("default"))) int vigil_ros2_transport_abi() {
  return vigil::exporter::detail::kRos2TransportAbi;
}

__attribute__((visibility("default"))) const char* vigil_ros2_transport_version() {
  return vigil::kVersion;
}

__attribute__((visibility("default"))) vigil::exporter::detail::Ros2Transport*
vigil_ros2_transport_create(const vigil::exporter::detail::Ros2TransportConfig& config,
                            std::string* error) {
  try {
    return vigil::exporter::detail::CycloneTransport::create(config, error);
  } catch (const std::exception& e) {
    if (error != nullptr) *error = e.what();
    return nullptr;
  }
}

}  // extern "C"
