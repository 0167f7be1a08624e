// Fuzz target: a shared-memory port segment as another process could leave it (truncated,
// corrupted, hostile), read the way `vigil supervise` reads it: header validation, then the ring
// (indices, records) and the mailboxes, each message decoded and checked, then aggregated.
// Whatever the bytes: no crash, no read outside the image, no undefined behaviour downstream,
// and every rejection names a field and says why.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/supervisor/component_aggregator.hpp"
#include "vigil/task/shm_messages.hpp"

namespace {

void check(bool ok) {
  if (!ok) __builtin_trap();
}

class NoPort final : public vigil::PortReader<vigil::Message> {
 public:
  std::size_t pop(vigil::Message* /*out*/, std::size_t /*max*/) noexcept override { return 0; }
  [[nodiscard]] std::size_t read_available() const noexcept override { return 0; }
  [[nodiscard]] std::size_t capacity() const noexcept override { return 1; }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace vigil;
  if (size > (1U << 20)) return 0;
  // The image in memory aligned like a mapping (the reader uses atomics on it).
  std::unique_ptr<std::byte, void (*)(std::byte*)> image(
      static_cast<std::byte*>(
          ::operator new (std::max<std::size_t>(size, 1), std::align_val_t{4096})),
      [](std::byte* p) { ::operator delete (p, std::align_val_t{4096}); });
  if (size > 0) std::memcpy(image.get(), data, size);

  const bus::ShmExpectation expect{kShmMessageSchema, ""};
  auto info = bus::validate_shm_image(image.get(), size, expect);
  if (!info) {
    check(!info.error().field.empty() && !info.error().message.empty());
    return 0;
  }
  const bus::ShmGeometry& g = info->geometry;
  check(g.segment_size == size);
  check(g.ring_offset + std::uint64_t{g.capacity} * g.record_size <= size);

  ComponentAggregator aggregator;
  RegistryEntry<Message> entry;
  entry.id = 1;
  entry.name = info->component_name;
  entry.port = std::make_shared<NoPort>();
  aggregator.on_join(entry);
  const auto feed = [&](Message& m) {
    std::string why;
    if (!check_shm_message(m, why)) {
      check(!why.empty());
      return;
    }
    aggregator.begin(entry);
    std::visit([&](const auto& x) { aggregator.on(entry, x); }, m);
    aggregator.end(entry, PortDrain{});
  };

  bus::ShmRingReader reader(image.get(), g);
  if (auto a = reader.attach(); !a) {
    check(!a.error().message.empty());
    return 0;
  }
  std::vector<std::byte> raw(static_cast<std::size_t>(g.record_size) * g.capacity);
  auto n = reader.pop_raw(raw.data(), g.capacity);
  if (n) {
    check(*n <= g.capacity);
    for (std::size_t i = 0; i < *n; ++i) {
      Message m;
      bus::ShmError why;
      if (bus::decode_shm_record(raw.data() + i * g.record_size, m, &why)) {
        feed(m);
      } else {
        check(!why.message.empty());
      }
    }
  }
  std::vector<std::byte> rec(g.record_size);
  for (std::uint32_t t = 0; t < g.type_count + 1; ++t) {
    if (!reader.read_mailbox(t, rec.data())) continue;
    Message m;
    if (bus::decode_shm_record(rec.data(), m, nullptr)) feed(m);
  }
  (void)reader.live();
  for (const auto& s : aggregator.snapshot()) check(s.name == info->component_name);
  return 0;
}
