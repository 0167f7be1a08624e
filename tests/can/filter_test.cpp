#include "vigil/can/filter.hpp"

#include <catch2/catch.hpp>

using vigil::can::Direction;
using vigil::can::Filter;
using vigil::can::FilterExpr;
using vigil::can::Frame;
using vigil::can::IdFormat;
using vigil::can::NodeMap;
namespace match = vigil::can::match;

namespace {
Filter compiled(const FilterExpr& e) {
  auto f = Filter::compile(e);
  REQUIRE(f.has_value());
  return *f;
}
Frame on_bus(Frame f, std::uint8_t bus) {
  f.bus = bus;
  return f;
}
const NodeMap kIdentity;
}  // namespace

TEST_CASE("The default filter accepts every frame", "[can][filter]") {
  const Filter f;
  CHECK(f.accepts_all());
  CHECK(f.matches(Frame::classic(0x123, {}), Direction::Rx, kIdentity));
  CHECK(FilterExpr().accepts_all());
  CHECK(compiled(FilterExpr()).accepts_all());
  CHECK(compiled(match::all_of({})).accepts_all());
  CHECK_FALSE(compiled(match::any_of({})).matches(Frame{}, Direction::Rx, kIdentity));
  CHECK_FALSE(compiled(match::reject_all()).matches(Frame{}, Direction::Rx, kIdentity));
}

TEST_CASE("Filters on bus, id list, id range and id mask", "[can][filter]") {
  const Frame a = Frame::classic(0x181, {1});
  const Frame b = Frame::classic(0x205, {1});
  const Frame c = Frame::classic(0x300, {1});
  const auto bus = compiled(match::bus({1, 3}));
  CHECK_FALSE(bus.matches(a, Direction::Rx, kIdentity));
  CHECK(bus.matches(on_bus(a, 1), Direction::Rx, kIdentity));
  CHECK(bus.matches(on_bus(a, 3), Direction::Rx, kIdentity));
  CHECK(compiled(match::bus({255})).matches(on_bus(a, 255), Direction::Rx, kIdentity));

  const auto ids = compiled(match::ids({0x300, 0x181, 0x181}));
  CHECK(ids.matches(a, Direction::Rx, kIdentity));
  CHECK_FALSE(ids.matches(b, Direction::Rx, kIdentity));
  CHECK(ids.matches(c, Direction::Rx, kIdentity));

  const auto range = compiled(match::id_range(0x200, 0x27F));
  CHECK_FALSE(range.matches(a, Direction::Rx, kIdentity));
  CHECK(range.matches(b, Direction::Rx, kIdentity));
  CHECK(range.matches(Frame::classic(0x200, {}), Direction::Rx, kIdentity));  // inclusive
  CHECK(range.matches(Frame::classic(0x27F, {}), Direction::Rx, kIdentity));
  CHECK_FALSE(range.matches(Frame::classic(0x280, {}), Direction::Rx, kIdentity));

  // SocketCAN-style: every TPDO1 (0x180 + node).
  const auto mask = compiled(match::id_mask(0x180, 0x780));
  CHECK(mask.matches(a, Direction::Rx, kIdentity));
  CHECK(mask.matches(Frame::classic(0x1FF, {}), Direction::Rx, kIdentity));
  CHECK_FALSE(mask.matches(b, Direction::Rx, kIdentity));
}

TEST_CASE("Filters on standard/extended, FD, remote and direction", "[can][filter]") {
  const Frame std_frame = Frame::classic(0x100, {1});
  const Frame ext_frame = Frame::classic(0x100, {1}, IdFormat::Extended);
  const auto ext = compiled(match::extended());
  CHECK(ext.matches(ext_frame, Direction::Rx, kIdentity));
  CHECK_FALSE(ext.matches(std_frame, Direction::Rx, kIdentity));
  const auto std_only = compiled(match::standard() && match::ids({0x100}));
  CHECK(std_only.matches(std_frame, Direction::Rx, kIdentity));
  CHECK_FALSE(std_only.matches(ext_frame, Direction::Rx, kIdentity));

  CHECK(compiled(match::fd()).matches(Frame::fd_frame(0x1, {1, 2}), Direction::Rx, kIdentity));
  CHECK_FALSE(compiled(match::fd()).matches(std_frame, Direction::Rx, kIdentity));
  CHECK(compiled(match::remote()).matches(Frame::remote(0x1, 8), Direction::Rx, kIdentity));

  const auto tx = compiled(match::direction(Direction::Tx));
  CHECK(tx.matches(std_frame, Direction::Tx, kIdentity));
  CHECK_FALSE(tx.matches(std_frame, Direction::Rx, kIdentity));
}

TEST_CASE("Filters on node ids go through the node mapping", "[can][filter]") {
  const NodeMap canopen = NodeMap::canopen();
  const auto arm = compiled(match::nodes({11, 12, 13, 14}));
  CHECK(arm.matches(Frame::classic(0x18B, {}), Direction::Rx, canopen));        // TPDO1 of 11
  CHECK(arm.matches(Frame::classic(0x70E, {}), Direction::Rx, canopen));        // heartbeat of 14
  CHECK_FALSE(arm.matches(Frame::classic(0x18F, {}), Direction::Rx, canopen));  // node 15
  // With the identity mapping the node is the id itself.
  CHECK_FALSE(arm.matches(Frame::classic(0x18B, {}), Direction::Rx, kIdentity));
  CHECK(arm.matches(Frame::classic(11, {}), Direction::Rx, kIdentity));

  const auto range = compiled(match::node_range(1, 4));
  CHECK(range.matches(Frame::classic(0x584, {}), Direction::Rx, canopen));
  CHECK_FALSE(range.matches(Frame::classic(0x585, {}), Direction::Rx, canopen));

  // J1939: everything the brakes (SA 0x0B) send, and one PGN.
  const NodeMap j1939 = NodeMap::j1939();
  const Frame ebc = Frame::classic(0x18FEFA0B, {}, IdFormat::Extended);
  const Frame ccvs = Frame::classic(0x18FEF121, {}, IdFormat::Extended);
  CHECK(compiled(match::nodes({0x0B})).matches(ebc, Direction::Rx, j1939));
  CHECK_FALSE(compiled(match::nodes({0x0B})).matches(ccvs, Direction::Rx, j1939));
  CHECK(compiled(match::functions({65265})).matches(ccvs, Direction::Rx, j1939));
  CHECK_FALSE(compiled(match::functions({65265})).matches(ebc, Direction::Rx, j1939));
}

TEST_CASE("Filters on payload bytes, e.g. a command byte", "[can][filter]") {
  // SDO download of 1 byte (command 0x2F) to node 11.
  const auto sdo = compiled(match::ids({0x60B}) && match::payload_byte(0, 0x2F));
  CHECK(
      sdo.matches(Frame::classic(0x60B, {0x2F, 0x00, 0x60, 0x00, 0x01}), Direction::Tx, kIdentity));
  CHECK_FALSE(sdo.matches(Frame::classic(0x60B, {0x40, 0x00, 0x60}), Direction::Tx, kIdentity));
  // The byte must exist: a short frame does not match.
  CHECK_FALSE(compiled(match::payload_byte(3, 0))
                  .matches(Frame::classic(0x1, {0, 0}), Direction::Rx, kIdentity));
  // Masked: the SDO command specifier is the top 3 bits.
  const auto ccs = compiled(match::payload_byte(0, 0x20, 0xE0));
  CHECK(ccs.matches(Frame::classic(0x60B, {0x2B}), Direction::Tx, kIdentity));
  CHECK(ccs.matches(Frame::classic(0x60B, {0x23}), Direction::Tx, kIdentity));
  CHECK_FALSE(ccs.matches(Frame::classic(0x60B, {0x40}), Direction::Tx, kIdentity));
  // CAN FD payloads are 64 bytes long.
  std::array<std::uint8_t, 64> bytes{};
  bytes[63] = 0x7E;
  const Frame fd = Frame::fd_frame(0x10, bytes);
  CHECK(compiled(match::payload_byte(63, 0x7E)).matches(fd, Direction::Rx, kIdentity));
}

TEST_CASE("Filters compose with and, or, not", "[can][filter]") {
  const FilterExpr e = match::bus({0}) &&
                       (match::ids({0x181, 0x182}) || match::id_range(0x200, 0x27F)) &&
                       !match::extended();
  CHECK(e.node().kind == FilterExpr::Kind::All);
  CHECK(e.node().children.size() == 3);  // flattened
  CHECK(e.to_string() ==
        "all(bus(0), any(ids(0x181, 0x182), id_range(0x200, 0x27F)), "
        "not(extended()))");
  const auto f = compiled(e);
  CHECK(f.text() == e.to_string());
  CHECK(f.matches(Frame::classic(0x182, {}), Direction::Rx, kIdentity));
  CHECK(f.matches(Frame::classic(0x210, {}), Direction::Rx, kIdentity));
  CHECK_FALSE(f.matches(Frame::classic(0x183, {}), Direction::Rx, kIdentity));
  CHECK_FALSE(f.matches(on_bus(Frame::classic(0x182, {}), 1), Direction::Rx, kIdentity));
  CHECK_FALSE(f.matches(Frame::classic(0x182, {}, IdFormat::Extended), Direction::Rx, kIdentity));

  // Neutral elements vanish; accept_all && x is x.
  CHECK((match::accept_all() && match::fd()).to_string() == "fd()");
  CHECK((match::reject_all() || match::fd()).to_string() == "fd()");
  CHECK(match::none_of(match::fd()).to_string() == "not(fd())");
}

TEST_CASE("Filter compilation rejects bad operands and deep nesting", "[can][filter]") {
  const auto fails = [](const FilterExpr& e, std::string_view what) {
    auto f = Filter::compile(e);
    REQUIRE_FALSE(f.has_value());
    CHECK(f.error().code == EINVAL);
    INFO(f.error().message);
    CHECK(f.error().message.find(what) != std::string::npos);
  };
  fails(match::id_range(0x300, 0x200), "lo is above hi");
  fails(match::ids({0x20000000}), "above 0x1FFFFFFF");
  fails(match::payload_byte(64, 0), "byte index 64");
  fails(match::payload_byte(0, 0x100), "at most 0xFF");
  fails(match::fd() && match::id_range(5, 1), "id_range(0x5, 0x1)");

  FilterExpr deep = match::fd();
  for (std::size_t i = 0; i < Filter::kMaxDepth; ++i) deep = !deep;
  CHECK(Filter::compile(deep).has_value());  // exactly kMaxDepth levels
  fails(!deep, "nested more than 32");
}

TEST_CASE("A compiled filter evaluates a wide AND/OR tree without growing its stack",
          "[can][filter]") {
  std::vector<FilterExpr> parts;
  for (std::uint32_t i = 0; i < 200; ++i) parts.push_back(match::ids({i * 2}));
  const auto any = compiled(match::any_of(parts));
  CHECK(any.matches(Frame::classic(398, {}), Direction::Rx, kIdentity));
  CHECK_FALSE(any.matches(Frame::classic(399, {}), Direction::Rx, kIdentity));
  CHECK(any.size() == 200 + 199);
}

TEST_CASE("A filter built by hand with duplicate operands compiles to a proper set",
          "[can][filter]") {
  auto node = std::make_shared<FilterExpr::Node>();
  node->kind = FilterExpr::Kind::Ids;
  node->values = {7, 5, 5, 7, 9};
  const auto f = compiled(FilterExpr(node));
  for (std::uint32_t id : {5U, 7U, 9U})
    CHECK(f.matches(Frame::classic(id, {}), Direction::Rx, kIdentity));
  for (std::uint32_t id : {4U, 6U, 8U, 10U}) {
    CHECK_FALSE(f.matches(Frame::classic(id, {}), Direction::Rx, kIdentity));
  }
}

TEST_CASE("A filter of simple conditions joined by AND is tested inline, as its program would",
          "[can][filter]") {
  SECTION("which filters take the inline test") {
    CHECK(compiled(match::bus({0}) && match::extended() && match::node_range(0, 0xFD))
              .is_simple_conjunction());
    CHECK(compiled(match::id_range(0x100, 0x1FF) && match::id_mask(0x180, 0x780) && match::fd() &&
                   match::direction(Direction::Tx))
              .is_simple_conjunction());
    CHECK(compiled(match::standard()).is_simple_conjunction());
    CHECK_FALSE(compiled(match::ids({0x181}) && match::standard()).is_simple_conjunction());
    CHECK_FALSE(compiled(match::standard() || match::fd()).is_simple_conjunction());
    CHECK_FALSE(compiled(!match::extended()).is_simple_conjunction());
    CHECK_FALSE(compiled(match::payload_byte(0, 0x2F) && match::bus({0})).is_simple_conjunction());
    CHECK_FALSE(Filter{}.is_simple_conjunction());  // accept-all has nothing to test
  }
  SECTION("contradictions pass no frame") {
    const auto none = [](const FilterExpr& e) {
      const Filter f = compiled(e);
      REQUIRE(f.is_simple_conjunction());
      for (std::uint32_t id = 0; id < 0x800; id += 7) {
        for (const bool ext : {false, true}) {
          const Frame fr = Frame::classic(id, {}, ext ? IdFormat::Extended : IdFormat::Standard);
          CHECK_FALSE(f.matches(fr, Direction::Rx, kIdentity));
          CHECK_FALSE(f.run(fr, Direction::Rx, kIdentity.map(fr)));
        }
      }
    };
    none(match::standard() && match::extended());
    none(match::id_range(0, 10) && match::id_range(20, 30));
    none(match::node_range(5, 6) && match::node_range(7, 8));
    none(match::id_mask(0x100, 0x700) && match::id_mask(0x200, 0x300));  // bit 0x100 disagrees
    none(match::reject_all() && match::standard());
    none(match::direction(Direction::Tx) && match::direction(Direction::Rx));
  }
  SECTION("two masks that agree are both tested") {
    const Filter f = compiled(match::id_mask(0x100, 0x700) && match::id_mask(0x001, 0x00F));
    REQUIRE(f.is_simple_conjunction());
    CHECK(f.matches(Frame::classic(0x181, {}), Direction::Rx, kIdentity));
    CHECK_FALSE(f.matches(Frame::classic(0x182, {}), Direction::Rx, kIdentity));
    CHECK_FALSE(f.matches(Frame::classic(0x281, {}), Direction::Rx, kIdentity));
  }
  SECTION("the same answer as the program, on random filters and frames") {
    std::uint64_t seed = 0x9E3779B97F4A7C15ULL;
    const auto next = [&seed](std::uint32_t n) {
      seed ^= seed << 13;
      seed ^= seed >> 7;
      seed ^= seed << 17;
      return static_cast<std::uint32_t>(seed % n);
    };
    const auto condition = [&]() -> FilterExpr {
      const std::uint32_t lo = next(0x800);
      switch (next(9)) {
        case 0:
          return match::bus(
              {static_cast<std::uint8_t>(next(4)), static_cast<std::uint8_t>(next(4) + 32)});
        case 1:
          return match::id_range(lo, lo + next(0x400));
        case 2:
          return match::id_mask(next(0x800), 0x700 >> next(4));
        case 3: {
          const std::uint32_t n = next(64);
          return match::node_range(n, n + next(64));
        }
        case 4:
          return match::standard();
        case 5:
          return match::extended();
        case 6:
          return match::fd();
        case 7:
          return match::remote();
        default:
          return match::direction(next(2) == 0 ? Direction::Rx : Direction::Tx);
      }
    };
    const NodeMap canopen = NodeMap::canopen();
    int simple = 0;
    int passed = 0;
    for (int k = 0; k < 400; ++k) {
      FilterExpr e = condition();
      for (std::uint32_t parts = next(4); parts > 0; --parts) e = e && condition();
      const Filter f = compiled(e);
      simple += f.is_simple_conjunction() ? 1 : 0;
      for (int i = 0; i < 200; ++i) {
        Frame fr = Frame::classic(next(0x800), {1, 2},
                                  next(2) == 0 ? IdFormat::Standard : IdFormat::Extended);
        fr.bus = static_cast<std::uint8_t>(next(2) == 0 ? next(4) : next(256));
        fr.fd = next(2) == 0;
        fr.rtr = !fr.fd && next(3) == 0;
        const Direction d = next(2) == 0 ? Direction::Rx : Direction::Tx;
        const bool got = f.matches(fr, d, canopen);
        INFO(e.to_string() << " on id " << fr.id << " bus " << int{fr.bus});
        REQUIRE(got == f.run(fr, d, canopen.map(fr)));
        passed += got ? 1 : 0;
      }
    }
    CHECK(simple == 400);  // every filter above is a simple conjunction
    CHECK(passed > 0);     // and some frames pass: the comparison is not all "no"
  }
}
