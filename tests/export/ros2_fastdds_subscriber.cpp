#include "ros2_fastdds_subscriber.hpp"

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <algorithm>
#include <cstring>

namespace vigil::test {

namespace {

namespace dds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;
using eprosima::fastcdr::Cdr;
using exporter::DiagnosticArrayMessage;
using exporter::DiagnosticStatusMessage;

// The CDR of diagnostic_msgs/msg/DiagnosticArray, field by field in declaration order (the
// types are final: no headers, XCDR1), as rosidl_typesupport_fastrtps_cpp would generate it.
void read(Cdr& c, DiagnosticArrayMessage& m) {
  c >> m.sec >> m.nanosec >> m.frame_id;  // header: stamp {sec, nanosec}, frame_id
  std::uint32_t n = 0;
  c >> n;
  m.status.assign(n, DiagnosticStatusMessage{});
  for (DiagnosticStatusMessage& s : m.status) {
    c >> s.level >> s.name >> s.message >> s.hardware_id;
    std::uint32_t k = 0;
    c >> k;
    s.values.assign(k, exporter::DiagnosticKeyValue{});
    for (auto& kv : s.values) c >> kv.key >> kv.value;
  }
}

void write(Cdr& c, const DiagnosticArrayMessage& m) {
  c << m.sec << m.nanosec << m.frame_id << static_cast<std::uint32_t>(m.status.size());
  for (const DiagnosticStatusMessage& s : m.status) {
    c << s.level << s.name << s.message << s.hardware_id
      << static_cast<std::uint32_t>(s.values.size());
    for (const auto& kv : s.values) c << kv.key << kv.value;
  }
}

std::uint32_t cdr_size(const DiagnosticArrayMessage& m) {
  // An upper bound: each field at most 3 bytes of padding, strings with length and NUL.
  std::size_t n = 4 + 8 + 8 + m.frame_id.size() + 8;
  for (const auto& s : m.status) {
    n += 4 + 3 * 8 + s.name.size() + s.message.size() + s.hardware_id.size() + 8;
    for (const auto& kv : s.values) n += 16 + kv.key.size() + kv.value.size();
  }
  return static_cast<std::uint32_t>(n);
}

class DiagnosticArrayType final : public dds::TopicDataType {
 public:
  DiagnosticArrayType() {
    setName("diagnostic_msgs::msg::dds_::DiagnosticArray_");  // rmw's mangling of the ROS type
    m_typeSize = 64 * 1024;  // a first guess: payloads grow as needed (dynamic memory policy)
    m_isGetKeyDefined = false;
  }

  bool serialize(void* data, rtps::SerializedPayload_t* payload) override {
    const auto& m = *static_cast<const DiagnosticArrayMessage*>(data);
    const std::uint32_t need = cdr_size(m);
    if (payload->max_size < need) payload->reserve(need);
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->max_size);
    Cdr c(buffer, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    payload->encapsulation = c.endianness() == Cdr::BIG_ENDIANNESS ? CDR_BE : CDR_LE;
    try {
      c.serialize_encapsulation();
      write(c, m);
    } catch (...) {
      return false;
    }
    payload->length = static_cast<std::uint32_t>(c.getSerializedDataLength());
    return true;
  }

  bool deserialize(rtps::SerializedPayload_t* payload, void* data) override {
    auto& m = *static_cast<DiagnosticArrayMessage*>(data);
    if (payload->length < 4) return false;
    last_encapsulation = (payload->data[0] << 8) | payload->data[1];
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->length);
    Cdr c(buffer, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    try {
      c.read_encapsulation();
      payload->encapsulation = c.endianness() == Cdr::BIG_ENDIANNESS ? CDR_BE : CDR_LE;
      read(c, m);
    } catch (...) {
      return false;
    }
    return true;
  }

  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return cdr_size(*static_cast<const DiagnosticArrayMessage*>(data)); };
  }
  void* createData() override { return new DiagnosticArrayMessage(); }
  void deleteData(void* data) override { delete static_cast<DiagnosticArrayMessage*>(data); }
  bool getKey(void* /*data*/, rtps::InstanceHandle_t* /*handle*/, bool /*force_md5*/) override {
    return false;  // keyless, as every ROS 2 message
  }

  // Written by the reader's thread in deserialize, read by on_data_available on the same thread.
  int last_encapsulation = -1;
};

// rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_ in CDR, for a read-only reader: the gid
// (`gid_size` octets), then the nodes (bounded strings are strings on the wire).
class ParticipantEntitiesInfoType final : public dds::TopicDataType {
 public:
  explicit ParticipantEntitiesInfoType(int gid_size)
      : gid_size_(static_cast<std::size_t>(gid_size)) {
    setName("rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
    m_typeSize = 64 * 1024;
    m_isGetKeyDefined = false;
  }

  bool serialize(void* /*data*/, rtps::SerializedPayload_t* /*payload*/) override {
    return false;  // this side only reads
  }

  bool deserialize(rtps::SerializedPayload_t* payload, void* data) override {
    auto& m = *static_cast<RosParticipantInfo*>(data);
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->length);
    Cdr c(buffer, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    try {
      c.read_encapsulation();
      m.gid = gid(c);
      std::uint32_t n = 0;
      c >> n;
      m.nodes.assign(n, RosNodeInfo{});
      for (RosNodeInfo& node : m.nodes) {
        c >> node.node_namespace >> node.node_name;
        for (auto* seq : {&node.readers, &node.writers}) {
          std::uint32_t k = 0;
          c >> k;
          seq->clear();
          for (std::uint32_t i = 0; i < k; ++i) seq->push_back(gid(c));
        }
      }
    } catch (...) {
      return false;
    }
    return true;
  }

  std::function<std::uint32_t()> getSerializedSizeProvider(void* /*data*/) override {
    return [] { return 0U; };
  }
  void* createData() override { return new RosParticipantInfo(); }
  void deleteData(void* data) override { delete static_cast<RosParticipantInfo*>(data); }
  bool getKey(void* /*data*/, rtps::InstanceHandle_t* /*handle*/, bool /*force_md5*/) override {
    return false;
  }

 private:
  std::string gid(Cdr& c) const {
    std::string g(gid_size_, '\0');
    c.deserializeArray(reinterpret_cast<std::uint8_t*>(g.data()), g.size());
    return g;
  }
  std::size_t gid_size_;
};

// The discovery reader's listener: keeps every sample.
struct DiscoveryListener : dds::DataReaderListener {
  std::mutex* mutex = nullptr;
  std::vector<RosParticipantInfo>* samples = nullptr;
  void on_data_available(dds::DataReader* r) override {
    RosParticipantInfo m;
    dds::SampleInfo info;
    while (r->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::lock_guard lock(*mutex);
      samples->push_back(m);
    }
  }
};

}  // namespace

struct FastDdsDiagnosticsSubscriber::Impl : dds::DataReaderListener {
  dds::DomainParticipant* participant = nullptr;
  dds::Subscriber* subscriber = nullptr;
  dds::Topic* topic = nullptr;
  dds::DataReader* reader = nullptr;
  DiagnosticArrayType* type = nullptr;  // owned by the TypeSupport
  mutable std::mutex mutex;
  std::vector<DiagnosticArrayMessage> received;
  std::vector<int> encapsulations;
  std::size_t gid_size = 0;
  std::string writer_gid;
  std::vector<RosParticipantInfo> discovery;
  DiscoveryListener discovery_listener;

  void on_data_available(dds::DataReader* r) override {
    DiagnosticArrayMessage m;
    dds::SampleInfo info;
    while (r->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::lock_guard lock(mutex);
      received.push_back(m);
      encapsulations.push_back(type->last_encapsulation);
      // rmw_fastrtps_cpp: publisher_gid from sample_identity.writer_guid(), prefix then entity id.
      const rtps::GUID_t& g = info.sample_identity.writer_guid();
      std::string gid(std::max<std::size_t>(gid_size, 16), '\0');
      std::memcpy(gid.data(), g.guidPrefix.value, sizeof g.guidPrefix.value);
      std::memcpy(gid.data() + sizeof g.guidPrefix.value, g.entityId.value,
                  sizeof g.entityId.value);
      writer_gid = std::move(gid);
    }
  }
};

FastDdsDiagnosticsSubscriber::FastDdsDiagnosticsSubscriber(int domain, int gid_size)
    : impl_(std::make_unique<Impl>()) {
  impl_->gid_size = static_cast<std::size_t>(gid_size);
  impl_->discovery_listener.mutex = &impl_->mutex;
  impl_->discovery_listener.samples = &impl_->discovery;
  dds::DomainParticipantQos pq = dds::PARTICIPANT_QOS_DEFAULT;
  pq.name("vigil_test_fastdds");
  // UDPv4 on loopback only (no shared memory: the samples must cross the wire), with unicast
  // discovery: 127.0.0.1 as the initial peer (loopback has no multicast here).
  pq.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  pq.transport().user_transports.push_back(udp);
  rtps::Locator_t peer;
  peer.kind = LOCATOR_KIND_UDPv4;
  rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  pq.wire_protocol().builtin.initialPeersList.push_back(peer);
  pq.wire_protocol().builtin.avoid_builtin_multicast = true;
  impl_->participant = dds::DomainParticipantFactory::get_instance()->create_participant(
      static_cast<dds::DomainId_t>(domain), pq);
  if (impl_->participant == nullptr) {
    error_ = "Fast DDS: cannot create the participant";
    return;
  }
  impl_->type = new DiagnosticArrayType();
  dds::TypeSupport type(impl_->type);
  if (type.register_type(impl_->participant) != ReturnCode_t::RETCODE_OK) {
    error_ = "Fast DDS: cannot register the type";
    return;
  }
  impl_->topic = impl_->participant->create_topic("rt/diagnostics", type.get_type_name(),
                                                  dds::TOPIC_QOS_DEFAULT);
  impl_->subscriber = impl_->participant->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
  if (impl_->topic == nullptr || impl_->subscriber == nullptr) {
    error_ = "Fast DDS: cannot create the topic or the subscriber";
    return;
  }
  dds::DataReaderQos rq = dds::DATAREADER_QOS_DEFAULT;
  rq.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  rq.durability().kind = dds::VOLATILE_DURABILITY_QOS;
  rq.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  rq.history().depth = 10;
  rq.endpoint().history_memory_policy = rtps::DYNAMIC_RESERVE_MEMORY_MODE;
  impl_->reader = impl_->subscriber->create_datareader(impl_->topic, rq, impl_.get());
  if (impl_->reader == nullptr) {
    error_ = "Fast DDS: cannot create the reader";
    return;
  }
  if (gid_size == 0) return;
  dds::TypeSupport info_type(new ParticipantEntitiesInfoType(gid_size));
  if (info_type.register_type(impl_->participant) != ReturnCode_t::RETCODE_OK) {
    error_ = "Fast DDS: cannot register ParticipantEntitiesInfo_";
    return;
  }
  dds::Topic* discovery = impl_->participant->create_topic(
      "ros_discovery_info", info_type.get_type_name(), dds::TOPIC_QOS_DEFAULT);
  dds::DataReaderQos dq = dds::DATAREADER_QOS_DEFAULT;
  dq.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  dq.durability().kind = dds::TRANSIENT_LOCAL_DURABILITY_QOS;
  dq.history().kind = dds::KEEP_ALL_HISTORY_QOS;
  dq.endpoint().history_memory_policy = rtps::DYNAMIC_RESERVE_MEMORY_MODE;
  if (discovery == nullptr ||
      impl_->subscriber->create_datareader(discovery, dq, &impl_->discovery_listener) == nullptr) {
    error_ = "Fast DDS: cannot create the ros_discovery_info reader";
  }
}

FastDdsDiagnosticsSubscriber::~FastDdsDiagnosticsSubscriber() {
  if (impl_->participant == nullptr) return;
  (void)impl_->participant->delete_contained_entities();
  (void)dds::DomainParticipantFactory::get_instance()->delete_participant(impl_->participant);
}

std::vector<exporter::DiagnosticArrayMessage> FastDdsDiagnosticsSubscriber::received() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->received;
}

std::vector<RosParticipantInfo> FastDdsDiagnosticsSubscriber::discovery() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->discovery;
}

std::string FastDdsDiagnosticsSubscriber::writer_gid() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->writer_gid;
}

std::vector<int> FastDdsDiagnosticsSubscriber::encapsulations() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->encapsulations;
}

}  // namespace vigil::test
