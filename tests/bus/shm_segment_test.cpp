// The segment format's validation: every header field corrupted, truncation, indices outside the
// ring, bad records, a file shrunk under the reader. Run under ASan + UBSan too
// (`cmake --preset asan-ubsan`, target vigil_shm_tests): nothing may read out of bounds.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <functional>
#include <string>
#include <variant>

#include "shm_support.hpp"
#include "vigil/bus/shm_port.hpp"
#include "vigil/bus/shm_session.hpp"

using namespace vigil;
using namespace vigil::bus;
using vigil::test::Image;
using vigil::test::make_image;

namespace {

struct Small {
  std::uint64_t value = 0;
};
struct Flagged {
  std::uint64_t value = 0;
  bool flag = false;
  char text[23] = {};
};
using TestVariant = std::variant<Small, Flagged>;
constexpr ShmSchema kSchema = make_shm_schema<TestVariant>("vigil.test", 1);

bool check_test(TestVariant& m, std::string& why) {
  if (auto* f = std::get_if<Flagged>(&m)) {
    unsigned char b = 0;
    std::memcpy(&b, &f->flag, 1);
    if (b > 1) {
      why = "Flagged: flag is neither 0 nor 1";
      return false;
    }
    f->text[sizeof f->text - 1] = '\0';
  }
  return true;
}

ShmExpectation expect(std::string_view sup = "sup") { return ShmExpectation{kSchema, sup}; }

struct Mutation {
  const char* field;  // the field the error must name ("" = accepted)
  std::function<void(ShmSegmentHeader&)> apply;
};

}  // namespace

TEST_CASE("A fresh segment image validates and says who wrote it", "[shm][segment]") {
  Image img = make_image(kSchema, 16);
  auto info = validate_shm_image(img.base, img.size, expect());
  REQUIRE(info.has_value());
  CHECK(info->component_name == "comp");
  CHECK(info->supervisor_name == "sup");
  CHECK(info->process_name == "proc");
  CHECK(info->command_line == "proc --arg");
  CHECK(info->schema_name == "vigil.test");
  CHECK(info->pid == 4242);
  CHECK(info->geometry.capacity == 16);
  CHECK(info->geometry.segment_size == img.size);
  CHECK(info->geometry.ring_offset % kShmCacheLine == 0);
}

TEST_CASE("Capacity is rounded up to a power of two", "[shm][segment]") {
  CHECK(ShmGeometry::make(2, 8, 100).capacity == 128);
  CHECK(ShmGeometry::make(2, 8, 256).capacity == 256);
  CHECK(ShmGeometry::make(2, 8, 0).capacity == 1);
  CHECK(ShmGeometry::make(2, 8, 1U << 30).capacity == kShmMaxCapacity);
}

TEST_CASE("Every header field, corrupted, is rejected naming the field", "[shm][segment]") {
  const auto no_nul = [](auto& a) { std::memset(a, 'x', sizeof a); };
  const std::vector<Mutation> mutations = {
      {"magic", [](auto& h) { h.magic ^= 1; }},
      {"abi_version", [](auto& h) { h.abi_version = kShmAbiVersion + 1; }},
      {"abi_version", [](auto& h) { h.abi_version = 0; }},
      {"header_size", [](auto& h) { h.header_size = 64; }},
      {"segment_size", [](auto& h) { h.segment_size += 64; }},
      {"segment_size", [](auto& h) { h.segment_size = ~std::uint64_t{0}; }},
      {"schema_id", [](auto& h) { h.schema_id ^= 0x100; }},
      {"type_count", [](auto& h) { h.type_count = 3; }},
      {"payload_size", [](auto& h) { h.payload_size = 8; }},
      {"record_size", [](auto& h) { h.record_size += 8; }},
      {"capacity", [](auto& h) { h.capacity = 0; }},
      {"capacity", [](auto& h) { h.capacity = 12; }},
      {"capacity", [](auto& h) { h.capacity = kShmMaxCapacity * 2; }},
      {"segment_size", [](auto& h) { h.capacity = 32; }},  // a power of two, wrong for the size
      {"mailbox_offset", [](auto& h) { h.mailbox_offset = 0; }},
      {"ring_offset", [](auto& h) { h.ring_offset = h.segment_size - 8; }},
      {"pid", [](auto& h) { h.pid = 0; }},
      {"pid", [](auto& h) { h.pid = -5; }},
      {"supervisor_name", [&](auto& h) { no_nul(h.supervisor_name); }},
      {"supervisor_name", [](auto& h) { std::strcpy(h.supervisor_name, "../etc"); }},
      {"supervisor_name", [](auto& h) { std::strcpy(h.supervisor_name, "other"); }},
      {"component_name", [&](auto& h) { no_nul(h.component_name); }},
      {"component_name", [](auto& h) { h.component_name[0] = '\0'; }},
      {"process_name", [&](auto& h) { no_nul(h.process_name); }},
      {"schema_name", [&](auto& h) { no_nul(h.schema_name); }},
      {"command_line", [&](auto& h) { no_nul(h.command_line); }},
      {"state", [](auto& h) { h.state = 0; }},
      {"state", [](auto& h) { h.state = 7; }},
      {"exit_kind", [](auto& h) { h.exit_kind = 3; }},
      {"write_index", [](auto& h) { h.write_index = h.capacity + 1; }},
      {"write_index",
       [](auto& h) {
         h.read_index = 5;
         h.write_index = 4;
       }},
      {"write_index", [](auto& h) { h.write_index = ~std::uint64_t{0}; }},
      {"dropped", [](auto& h) { h.dropped = h.offered + 1; }},
      // Informative fields: any value would be harmless, but the writer set them once and the
      // constant part's checksum no longer matches.
      {"header_checksum", [](auto& h) { h.uid = 0xFFFFFFFF; }},
      {"header_checksum", [](auto& h) { h.start_ticks = ~std::uint64_t{0}; }},
      {"header_checksum", [](auto& h) { h.created_unix_ns = -1; }},
      {"header_checksum", [](auto& h) { h.component_index = 0xFFFFFFFF; }},
      {"header_checksum", [](auto& h) { h.flags = 0xFFFFFFFF; }},
      {"header_checksum", [](auto& h) { h.pid += 1; }},
      {"header_checksum", [](auto& h) { h.component_name[0] = 'k'; }},
      {"header_checksum", [](auto& h) { h.command_line[3] = 'X'; }},
      {"header_checksum", [](auto& h) { h.header_checksum ^= 1; }},
      {"reserved0", [](auto& h) { h.reserved0 = 1; }},
      {"reserved1", [](auto& h) { h.reserved1 = 0xFFFFFFFF; }},
      {"reserved2", [](auto& h) { h.reserved2[55] = 1; }},
      // Fields that change after creation: any value is accepted at open.
      {"", [](auto& h) { h.exit_code = -1; }},
      {"",
       [](auto& h) {
         h.daemon_heartbeat_ns = -1;
         h.daemon_pid = -1;
       }},
      {"", [](auto& h) { h.drains = ~std::uint64_t{0}; }},
      {"",
       [](auto& h) {
         h.read_index = 1000;
         h.write_index = 1000 + h.capacity;
       }},
  };
  for (const Mutation& m : mutations) {
    Image img = make_image(kSchema, 16);
    m.apply(img.header());
    auto r = validate_shm_image(img.base, img.size, expect());
    INFO("mutation of " << (m.field[0] != '\0' ? m.field : "an informative field"));
    if (m.field[0] == '\0') {
      CHECK(r.has_value());
    } else {
      REQUIRE_FALSE(r.has_value());
      CHECK(r.error().field == m.field);
      CHECK_FALSE(r.error().message.empty());
    }
  }
}

TEST_CASE("A header still being created is young, whatever its other fields hold",
          "[shm][segment]") {
  // Right after ftruncate every byte is zero; the writer stores `state` last. A daemon that
  // reads the segment then must retry it (error on `state`), not reject it for its magic.
  Image img = make_image(kSchema, 16);
  std::memset(img.base, 0, sizeof(ShmSegmentHeader));
  auto r = validate_shm_image(img.base, img.size, expect());
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().field == "state");
  CHECK(r.error().message == "still being created");
  // Half written: magic and version there, the rest not yet.
  Image half = make_image(kSchema, 16);
  half.header().state = 0;
  half.header().schema_id = 0;
  half.header().pid = 0;
  auto h = validate_shm_image(half.base, half.size, expect());
  REQUIRE_FALSE(h.has_value());
  CHECK(h.error().field == "state");
  // Once Open, the same zero fields are corruption.
  half.header().state = static_cast<std::uint32_t>(ShmState::Open);
  auto o = validate_shm_image(half.base, half.size, expect());
  REQUIRE_FALSE(o.has_value());
  CHECK(o.error().field == "schema_id");
}

TEST_CASE("Errors say what is wrong in words", "[shm][segment]") {
  Image img = make_image(kSchema, 16);
  img.header().abi_version = 9;
  auto r = validate_shm_image(img.base, img.size, expect());
  REQUIRE_FALSE(r);
  CHECK(r.error().to_string() ==
        "abi_version: segment format version 9, this reader reads version 2 (different vigil "
        "releases)");
  Image img2 = make_image(kSchema, 16);
  img2.header().write_index = 100;
  auto r2 = validate_shm_image(img2.base, img2.size, expect());
  REQUIRE_FALSE(r2);
  CHECK(r2.error().to_string() ==
        "write_index: 100 is 100 records ahead of read_index 0; the ring holds 16");
}

TEST_CASE("Truncated images are rejected", "[shm][segment]") {
  Image img = make_image(kSchema, 16);
  for (const std::size_t n : {std::size_t{0}, std::size_t{1}, sizeof(ShmSegmentHeader) - 1}) {
    auto r = validate_shm_image(img.base, n, expect());
    REQUIRE_FALSE(r);
    CHECK(r.error().field == "file");
    CHECK_THAT(r.error().message, Catch::Contains("truncated"));
  }
  for (const std::size_t n : {sizeof(ShmSegmentHeader), img.size - 1, img.size / 2}) {
    auto r = validate_shm_image(img.base, n, expect());
    REQUIRE_FALSE(r);
    CHECK(r.error().field == "segment_size");
    CHECK_THAT(r.error().message, Catch::Contains("truncated"));
  }
  CHECK_FALSE(validate_shm_image(nullptr, 1000, expect()));
}

TEST_CASE("Any single corrupted header byte never crashes the validator", "[shm][segment]") {
  Image pristine = make_image(kSchema, 8);
  int format_changes = 0;
  int format_rejected = 0;
  for (std::size_t off = 0; off < sizeof(ShmSegmentHeader); ++off) {
    for (const unsigned v : {0x00U, 0x01U, 0x7FU, 0x80U, 0xFFU}) {
      Image img = make_image(kSchema, 8);
      auto* p = reinterpret_cast<unsigned char*>(img.base) + off;
      if (*p == v) continue;
      *p = static_cast<unsigned char>(v);
      const bool ok = validate_shm_image(img.base, img.size, expect()).has_value();
      // The first 512 bytes (written once, under the checksum), the checksum and the reserved
      // fields: any change there is rejected.
      const bool reserved = (off >= offsetof(ShmSegmentHeader, reserved0) &&
                             off < offsetof(ShmSegmentHeader, reserved0) + 4) ||
                            (off >= offsetof(ShmSegmentHeader, reserved1) &&
                             off < offsetof(ShmSegmentHeader, reserved1) + 4);
      if (off < kShmConstantBytes || off >= offsetof(ShmSegmentHeader, header_checksum) ||
          reserved) {
        ++format_changes;
        format_rejected += ok ? 0 : 1;
      }
    }
  }
  CHECK(format_rejected == format_changes);
  CHECK(validate_shm_image(pristine.base, pristine.size, expect()).has_value());
}

TEST_CASE("File checks: owner, mode, group, size", "[shm][segment]") {
  platform::ShmFileInfo f;
  f.uid = 1000;
  f.mode = 0600;
  f.size = 4096;
  CHECK(check_shm_file(f, 1000, false).has_value());
  CHECK_FALSE(check_shm_file(f, 1001, false).has_value());
  f.mode = 0644;
  auto r = check_shm_file(f, 1000, false);
  REQUIRE_FALSE(r);
  CHECK_THAT(r.error().message, Catch::Contains("every user"));
  f.mode = 0660;
  CHECK_FALSE(check_shm_file(f, 1000, false).has_value());
  CHECK(check_shm_file(f, 1000, true).has_value());
  f.mode = 0600;
  f.size = kShmMaxSegmentSize + 1;
  CHECK_FALSE(check_shm_file(f, 1000, false).has_value());
}

TEST_CASE("Supervisor names and segment names", "[shm][segment]") {
  CHECK(valid_supervisor_name("robot_1-a"));
  CHECK_FALSE(valid_supervisor_name(""));
  CHECK_FALSE(valid_supervisor_name("a/b"));
  CHECK_FALSE(valid_supervisor_name("a.b"));
  CHECK_FALSE(valid_supervisor_name(std::string(32, 'a')));
  CHECK(shm_segment_name("robot", 1234, 2) == "/vigil.robot.1234.2");
  CHECK(shm_segment_prefix("robot") == "vigil.robot.");
}

// --- real segments: the reader against a misbehaving writer
// ---------------------------------------

namespace {

struct RealSegment {
  RealSegment()
      : name(vigil::test::unique_supervisor_name()),
        cleanup(name),
        session(*ShmSession::open(ShmOptions{name, "", 0, {}}, kSchema)),
        segment(std::move(*session->create("comp", 8))),
        producer(segment->data(), segment->geometry(), 0) {}

  [[nodiscard]] ShmSegmentHeader& header() const {
    return *static_cast<ShmSegmentHeader*>(segment->data());
  }
  [[nodiscard]] std::byte* record(std::uint64_t index) const {
    const auto& g = segment->geometry();
    return static_cast<std::byte*>(segment->data()) + g.ring_offset +
           (index % g.capacity) * g.record_size;
  }
  /// Rewrites the header of record `index` in place through `f` (a producer gone wrong).
  template <class F>
  void edit_header(std::uint64_t index, F f) const {
    ShmRecordHeader h;
    std::memcpy(&h, record(index), sizeof h);
    f(h);
    std::memcpy(record(index), &h, sizeof h);
  }
  [[nodiscard]] ShmReader<TestVariant> reader() const {
    auto r = ShmReader<TestVariant>::open(segment->name(), ShmExpectation{kSchema, name},
                                          platform::effective_uid(), false);
    REQUIRE(r.has_value());
    return std::move(*r);
  }

  std::string name;
  vigil::test::ShmCleanup cleanup;
  std::shared_ptr<ShmSession> session;
  std::unique_ptr<ShmSegment> segment;
  ShmProducer<TestVariant> producer;
};

}  // namespace

TEST_CASE("Segments are created owner-only and found by their prefix", "[shm][segment]") {
  RealSegment s;
  const auto names = platform::list_shared_memory(shm_segment_prefix(s.name));
  REQUIRE(names.size() == 1);
  CHECK(names[0] == s.segment->name());
  auto mem = platform::SharedMemory::open(s.segment->name(), kShmMaxSegmentSize);
  REQUIRE(mem);
  CHECK(mem->info().mode == 0600);
  CHECK(mem->info().uid == platform::effective_uid());
}

TEST_CASE("The directory watch reports only the files of the prefix it is given",
          "[shm][segment]") {
  auto w = platform::ShmDirectoryWatch::open();
  REQUIRE(w.has_value());
  const std::string ours = vigil::test::unique_supervisor_name();
  const std::string other = vigil::test::unique_supervisor_name();
  vigil::test::ShmCleanup c1(ours);
  vigil::test::ShmCleanup c2(other);
  (void)w->consume();
  {
    auto s = ShmSession::open(ShmOptions{other, "", 0, {}}, kSchema);
    REQUIRE(s.has_value());
    REQUIRE((*s)->create("comp", 8).has_value());
  }
  CHECK_FALSE(w->consume(shm_segment_prefix(ours)));  // another daemon's segment
  {
    auto s = ShmSession::open(ShmOptions{ours, "", 0, {}}, kSchema);
    REQUIRE(s.has_value());
    REQUIRE((*s)->create("comp", 8).has_value());
  }
  CHECK(w->consume(shm_segment_prefix(ours)));
  CHECK_FALSE(w->consume(shm_segment_prefix(ours)));  // consumed
}

TEST_CASE("The reader pops what the producer pushed, in order, across the ring's end",
          "[shm][segment]") {
  RealSegment s;
  auto r = s.reader();
  TestVariant out[8];
  std::uint64_t seqs[8];
  std::uint64_t next = 1;
  for (int round = 0; round < 5; ++round) {
    for (int i = 0; i < 5; ++i) REQUIRE(s.producer.push(Small{next + static_cast<unsigned>(i)}));
    auto n = r.pop(out, seqs, 8, &check_test);
    REQUIRE(n);
    REQUIRE(*n == 5);
    for (std::size_t i = 0; i < 5; ++i) {
      CHECK(std::get<Small>(out[i]).value == next + i);
      CHECK(seqs[i] == next + i);
    }
    next += 5;
  }
}

TEST_CASE("pop_each hands records in place and consumes only those it accepted", "[shm][segment]") {
  RealSegment s;
  for (std::uint64_t i = 1; i <= 5; ++i) REQUIRE(s.producer.push(Small{10 * i}));
  ShmRingReader ring(s.segment->data(), s.segment->geometry());
  REQUIRE(ring.attach());
  struct Seen {
    std::vector<std::uint64_t> values;
    std::size_t accept = 0;
  } seen;
  const auto take = [](void* ctx, const std::byte* rec) noexcept {
    auto& c = *static_cast<Seen*>(ctx);
    if (c.values.size() == c.accept) return false;
    Small v;
    std::memcpy(&v, rec + sizeof(ShmRecordHeader), sizeof v);
    c.values.push_back(v.value);
    return true;
  };
  seen.values.reserve(8);  // nothing allocates inside the guard
  seen.accept = 3;
  auto n = ring.pop_each(8, take, &seen);
  REQUIRE(n);
  CHECK(*n == 3);
  CHECK(seen.values == std::vector<std::uint64_t>{10, 20, 30});
  CHECK(ring.read_index() == 3);
  CHECK(s.header().read_index == 3);  // published: the producer may reuse three slots
  seen.accept = 8;
  n = ring.pop_each(8, take, &seen);
  REQUIRE(n);
  CHECK(*n == 2);  // the two left, from where the first call stopped
  CHECK(seen.values == std::vector<std::uint64_t>{10, 20, 30, 40, 50});
  CHECK(s.header().read_index == 5);
  n = ring.pop_each(8, take, &seen);
  REQUIRE(n);
  CHECK(*n == 0);
}

TEST_CASE("A full ring refuses the push, and a drop is counted and kept in the mailbox",
          "[shm][segment]") {
  RealSegment s;
  for (int i = 0; i < 8; ++i) REQUIRE(s.producer.push(Small{static_cast<std::uint64_t>(i)}));
  CHECK_FALSE(s.producer.push(Small{99}));
  s.producer.drop(Small{99}, 1);
  auto r = s.reader();
  auto live = r.live();
  REQUIRE(live);
  CHECK(live->dropped == 1);
  CHECK(live->offered == 9);
  TestVariant out[16];
  auto n = r.pop(out, nullptr, 16, &check_test);
  REQUIRE(n);
  CHECK(*n == 8);
  std::vector<TestVariant> late;
  REQUIRE(r.mailboxes(late, r.last_seq(), ~std::uint64_t{0}, &check_test));
  REQUIRE(late.size() == 1);
  CHECK(std::get<Small>(late[0]).value == 99);
}

TEST_CASE("Indices that point outside the ring reject the segment", "[shm][segment]") {
  RealSegment s;
  for (int i = 0; i < 3; ++i) REQUIRE(s.producer.push(Small{1}));
  TestVariant out[8];
  SECTION("write index beyond read index + capacity") {
    auto r = s.reader();
    s.header().write_index = 3 + 8 + 1;
    auto n = r.pop(out, nullptr, 8, &check_test);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "write_index");
    CHECK(r.error().has_value());
    CHECK_FALSE(r.live().has_value());
  }
  SECTION("write index moved backwards") {
    auto r = s.reader();
    REQUIRE(r.pop(out, nullptr, 8, &check_test).value() == 3);
    s.header().write_index = 1;
    auto n = r.pop(out, nullptr, 8, &check_test);
    REQUIRE_FALSE(n);
    CHECK_THAT(n.error().message, Catch::Contains("behind"));
  }
  SECTION("huge indices at open") {
    s.header().read_index = ~std::uint64_t{0} - 2;
    s.header().write_index = 5;
    auto r = ShmReader<TestVariant>::open(s.segment->name(), ShmExpectation{kSchema, s.name},
                                          platform::effective_uid(), false);
    REQUIRE_FALSE(r);
    CHECK(r.error().field == "write_index");
  }
  SECTION("indices far along but consistent are read modulo the capacity") {
    REQUIRE(s.producer.push(Small{1}));
    REQUIRE(s.producer.push(Small{1}));
    s.header().read_index = (1ULL << 40) + 3;
    s.header().write_index = (1ULL << 40) + 5;
    auto r = s.reader();
    auto n = r.pop(out, nullptr, 8, &check_test);
    REQUIRE(n);  // two records, wherever index mod 8 points: inside the ring
    CHECK(*n == 2);
  }
}

TEST_CASE("Bad records reject the segment: type, size, sequence, contents", "[shm][segment]") {
  RealSegment s;
  REQUIRE(s.producer.push(Small{1}));
  REQUIRE(s.producer.push(Flagged{2, true, "ok"}));
  TestVariant out[8];
  // A bad second record: the good first one is still handed out (its counters count), the
  // segment is marked corrupt, and the next pop says why.
  const auto pop_after_good = [&](ShmReader<TestVariant>& r) {
    auto first = r.pop(out, nullptr, 8, &check_test);
    REQUIRE(first);
    CHECK(*first == 1);
    CHECK(std::get<Small>(out[0]).value == 1);
    CHECK(r.error().has_value());
    return r.pop(out, nullptr, 8, &check_test);
  };
  SECTION("type") {
    s.edit_header(0, [](ShmRecordHeader& h) { h.type = 7; });
    auto r = s.reader();
    auto n = r.pop(out, nullptr, 8, &check_test);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "record.type");
  }
  SECTION("size") {
    s.edit_header(1, [](ShmRecordHeader& h) { h.size = 4000; });
    auto r = s.reader();
    auto n = pop_after_good(r);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "record.size");
  }
  SECTION("sequence") {
    s.edit_header(1, [](ShmRecordHeader& h) { h.seq = 1; });  // same as the first record's
    auto r = s.reader();
    auto n = pop_after_good(r);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "record.seq");
    CHECK(n.error().message == "sequence 1 does not follow 1");
    CHECK(r.error().has_value());  // nothing more is read from it
    CHECK_FALSE(r.pop(out, nullptr, 8, &check_test));
  }
  SECTION("an earlier record's contents are judged before a later record's type") {
    REQUIRE(s.producer.push(Flagged{3, false, "x"}));
    auto* payload = s.record(1) + sizeof(ShmRecordHeader);
    payload[offsetof(Flagged, flag)] = std::byte{5};
    s.edit_header(2, [](ShmRecordHeader& h) { h.type = 9; });
    auto r = s.reader();
    auto n = pop_after_good(r);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "record");
  }
  SECTION("contents: a bool that is neither 0 nor 1") {
    auto* payload = s.record(1) + sizeof(ShmRecordHeader);
    payload[offsetof(Flagged, flag)] = std::byte{2};
    auto r = s.reader();
    auto n = pop_after_good(r);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "record");
    CHECK_THAT(n.error().message, Catch::Contains("neither 0 nor 1"));
  }
  SECTION("an unterminated string is terminated by the check") {
    auto* payload = s.record(1) + sizeof(ShmRecordHeader);
    std::memset(payload + offsetof(Flagged, text), 'z', sizeof(Flagged::text));
    auto r = s.reader();
    auto n = r.pop(out, nullptr, 8, &check_test);
    REQUIRE(n);
    CHECK(std::strlen(std::get<Flagged>(out[1]).text) == sizeof(Flagged::text) - 1);
  }
}

TEST_CASE("A hostile mailbox is rejected, a busy one is skipped", "[shm][segment]") {
  RealSegment s;
  s.producer.drop(Small{5}, 1);
  const auto& g = s.segment->geometry();
  auto* box = static_cast<std::byte*>(s.segment->data()) + g.mailbox_offset;  // type 0's
  SECTION("wrong type in a mailbox") {
    ShmRecordHeader h;
    std::memcpy(&h, box + 8, sizeof h);
    h.type = 1;
    std::memcpy(box + 8, &h, sizeof h);
    auto r = s.reader();
    std::vector<TestVariant> out;
    auto n = r.mailboxes(out, 0, ~std::uint64_t{0}, &check_test);
    REQUIRE_FALSE(n);
    CHECK(n.error().field == "mailbox");
  }
  SECTION("a version stuck odd (a writer that never finishes)") {
    std::uint64_t v = 0;
    std::memcpy(&v, box, 8);
    v |= 1;
    std::memcpy(box, &v, 8);
    auto r = s.reader();
    std::vector<TestVariant> out;
    auto n = r.mailboxes(out, 0, ~std::uint64_t{0}, &check_test);
    REQUIRE(n);
    CHECK(*n == 0);
  }
}

TEST_CASE("Segments open to other users, or of another schema, are refused at open",
          "[shm][segment]") {
  RealSegment s;
  SECTION("mode 0644") {
    const int fd = ::shm_open(s.segment->name().c_str(), O_RDWR, 0);
    REQUIRE(fd >= 0);
    REQUIRE(::fchmod(fd, 0644) == 0);
    ::close(fd);
    auto r = ShmReader<TestVariant>::open(s.segment->name(), ShmExpectation{kSchema, s.name},
                                          platform::effective_uid(), false);
    REQUIRE_FALSE(r);
    CHECK(r.error().field == "file");
  }
  SECTION("another schema") {
    constexpr ShmSchema other = make_shm_schema<TestVariant>("vigil.test", 2);
    auto r = ShmReader<TestVariant>::open(s.segment->name(), ShmExpectation{other, s.name},
                                          platform::effective_uid(), false);
    REQUIRE_FALSE(r);
    CHECK(r.error().field == "schema_id");
  }
  SECTION("another owner") {
    auto r = ShmReader<TestVariant>::open(s.segment->name(), ShmExpectation{kSchema, s.name},
                                          platform::effective_uid() + 1, false);
    REQUIRE_FALSE(r);
    CHECK_THAT(r.error().message, Catch::Contains("owned by uid"));
  }
}

TEST_CASE("A segment truncated under the reader is an error, not a bus error", "[shm][segment]") {
  RealSegment s;
  REQUIRE(s.producer.push(Small{1}));
  auto r = s.reader();
  const int fd = ::shm_open(s.segment->name().c_str(), O_RDWR, 0);
  REQUIRE(fd >= 0);
  REQUIRE(::ftruncate(fd, 0) == 0);
  ::close(fd);
  auto live = r.live();
  REQUIRE_FALSE(live);
  CHECK(live.error().field == "file");
  CHECK_THAT(live.error().message, Catch::Contains("truncated"));
  TestVariant out[4];
  CHECK_FALSE(r.pop(out, nullptr, 4, &check_test).has_value());
  // Opening it again sees an empty file.
  auto again = ShmReader<TestVariant>::open(s.segment->name(), ShmExpectation{kSchema, s.name},
                                            platform::effective_uid(), false);
  REQUIRE_FALSE(again);
  CHECK_THAT(again.error().message, Catch::Contains("empty"));
  // Give the writer its pages back before it closes the segment (the writer is not guarded).
  const int fd2 = ::shm_open(s.segment->name().c_str(), O_RDWR, 0);
  REQUIRE(fd2 >= 0);
  REQUIRE(::ftruncate(fd2, static_cast<off_t>(s.segment->geometry().segment_size)) == 0);
  ::close(fd2);
}

TEST_CASE("Every header field written over after the reader opened the segment is named",
          "[shm][segment][corruption]") {
  struct Over {
    const char* field;
    std::size_t offset;
    std::size_t size;
  };
#define VIGIL_OVER(f) \
  Over { #f, offsetof(ShmSegmentHeader, f), sizeof(ShmSegmentHeader::f) }
  const std::vector<Over> fields = {
      VIGIL_OVER(magic),
      VIGIL_OVER(abi_version),
      VIGIL_OVER(header_size),
      VIGIL_OVER(segment_size),
      VIGIL_OVER(schema_id),
      VIGIL_OVER(type_count),
      VIGIL_OVER(payload_size),
      VIGIL_OVER(record_size),
      VIGIL_OVER(capacity),
      VIGIL_OVER(mailbox_offset),
      VIGIL_OVER(ring_offset),
      VIGIL_OVER(pid),
      VIGIL_OVER(uid),
      VIGIL_OVER(start_ticks),
      VIGIL_OVER(created_unix_ns),
      VIGIL_OVER(component_index),
      VIGIL_OVER(flags),
      VIGIL_OVER(supervisor_name),
      VIGIL_OVER(component_name),
      VIGIL_OVER(process_name),
      VIGIL_OVER(schema_name),
      VIGIL_OVER(command_line),
      VIGIL_OVER(state),
      VIGIL_OVER(exit_kind),
      VIGIL_OVER(exit_code),
      VIGIL_OVER(reserved0),
      VIGIL_OVER(daemon_heartbeat_ns),
      VIGIL_OVER(daemon_pid),
      VIGIL_OVER(reserved1),
      VIGIL_OVER(write_index),
      VIGIL_OVER(dropped),
      VIGIL_OVER(offered),
      VIGIL_OVER(read_index),
      VIGIL_OVER(drains),
      VIGIL_OVER(header_checksum),
      VIGIL_OVER(reserved2),
  };
#undef VIGIL_OVER
  for (const Over& f : fields) {
    INFO("field " << f.field);
    CHECK(std::string(shm_header_field(f.offset)) == f.field);
    RealSegment s;
    for (int i = 0; i < 3; ++i) REQUIRE(s.producer.push(Small{static_cast<std::uint64_t>(i)}));
    auto r = s.reader();
    TestVariant out[8];
    REQUIRE(r.pop(out, nullptr, 8, &check_test).value() == 3);
    r.heartbeat(1000, 77);  // the daemon's own fields now hold what it wrote
    REQUIRE(r.live());
    REQUIRE(r.verify());
    auto* bytes = static_cast<std::byte*>(s.segment->data()) + f.offset;
    for (std::size_t i = 0; i < f.size; ++i) bytes[i] ^= std::byte{0xA5};
    // What a daemon does: header checks at their rate, a drain, the writer pushes, again.
    bool found = !r.verify() || !r.live();
    if (!found) {
      (void)s.producer.push(Small{9});
      found = !r.live() || !r.verify();
    }
    REQUIRE(found);
    REQUIRE(r.error().has_value());
    CHECK(r.error()->field == f.field);
    CHECK_FALSE(r.error()->message.empty());
    // Never read again.
    CHECK_FALSE(r.pop(out, nullptr, 8, &check_test));
    CHECK_FALSE(r.live());
  }
}

TEST_CASE("The header checksum covers the constant part, word by word", "[shm][segment]") {
  Image img = make_image(kSchema, 16);
  const ShmSegmentHeader& h = img.header();
  CHECK(h.header_checksum == shm_header_checksum(&h));
  for (std::size_t bit = 0; bit < kShmConstantBytes * 8; bit += 61) {
    ShmSegmentHeader c = h;
    reinterpret_cast<unsigned char*>(&c)[bit / 8] ^= static_cast<unsigned char>(1U << (bit % 8));
    CHECK(shm_header_checksum(&c) != h.header_checksum);
    CHECK(shm_constant_difference(c, h) != nullptr);
  }
  // The fields that change after creation are outside it.
  ShmSegmentHeader c = h;
  c.write_index = 5;
  c.state = 2;
  CHECK(shm_header_checksum(&c) == h.header_checksum);
  CHECK(shm_constant_difference(c, h) == nullptr);
}
