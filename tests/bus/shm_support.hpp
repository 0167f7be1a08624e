#pragma once
// Shared by the shared-memory tests: unique supervisor names, clean-up of /dev/shm, images.
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "vigil/bus/shm_layout.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/platform/shm.hpp"

namespace vigil::test {

/// A supervisor name no other test (or test process) uses: "t<pid>x<n>".
inline std::string unique_supervisor_name() {
  static std::atomic<int> n{0};
  return "t" + std::to_string(::getpid()) + "x" + std::to_string(n++);
}

/// Removes every segment of supervisor `name` when it goes out of scope (and at creation).
struct ShmCleanup {
  explicit ShmCleanup(std::string n) : name(std::move(n)) { clean(); }
  ~ShmCleanup() { clean(); }
  ShmCleanup(const ShmCleanup&) = delete;
  ShmCleanup& operator=(const ShmCleanup&) = delete;
  void clean() const {
    for (const auto& s : platform::list_shared_memory(bus::shm_segment_prefix(name))) {
      (void)platform::unlink_shared_memory(s);
    }
  }
  [[nodiscard]] std::size_t count() const {
    return platform::list_shared_memory(bus::shm_segment_prefix(name)).size();
  }
  std::string name;
};

/// A segment image in ordinary memory, aligned like a mapping.
struct Image {
  explicit Image(std::size_t n) : bytes(n + 4096) {
    auto p = reinterpret_cast<std::uintptr_t>(bytes.data());
    base = reinterpret_cast<std::byte*>((p + 4095) & ~std::uintptr_t{4095});
    size = n;
  }
  [[nodiscard]] bus::ShmSegmentHeader& header() const {
    return *reinterpret_cast<bus::ShmSegmentHeader*>(base);
  }
  std::vector<std::byte> bytes;
  std::byte* base = nullptr;
  std::size_t size = 0;
};

/// An initialised image for `schema` with a ring of `capacity` records.
inline Image make_image(const bus::ShmSchema& schema, std::uint32_t capacity,
                        std::string_view supervisor = "sup", std::string_view component = "comp") {
  const auto g = bus::ShmGeometry::make(schema.type_count, schema.payload_size, capacity);
  Image img(g.segment_size);
  bus::ShmIdentity who;
  who.supervisor_name = supervisor;
  who.component_name = component;
  who.pid = 4242;
  who.uid = 1000;
  who.start_ticks = 123;
  who.process_name = "proc";
  who.command_line = "proc --arg";
  bus::init_shm_segment(img.base, g, schema, who);
  return img;
}

}  // namespace vigil::test
