#pragma once
/// @file
/// CAN frame filters: composable predicates (`FilterExpr`, built with the `match::` functions
/// and `&&`, `||`, `!`, or loaded from YAML, see can_config.hpp) compiled into a flat program
/// (`Filter`) that the sniffer runs on the CAN I/O thread.
///
/// Design: building and compiling allocate and run on ordinary threads; `Filter::matches` does
/// not allocate, lock, throw or make a system call. A compiled filter is immutable, so the
/// sniffer can publish a new one through an atomic pointer while the I/O thread keeps using the
/// old one until it reaches a quiescent point (see sniffer.hpp). The program is postfix with
/// binary AND/OR, so its stack never holds more than the expression's nesting depth plus one
/// value; compiling refuses expressions nested deeper than `Filter::kMaxDepth`.
///
/// @code
/// using namespace vigil::can;
/// FilterExpr f = match::bus({0}) && (match::ids({0x181, 0x182}) || match::id_range(0x200, 0x27F))
///                && !match::extended() && match::payload_byte(0, 0x2F);
/// auto compiled = Filter::compile(f);     // expected<Filter, Error>
/// sniffer.set_filter(f);                  // or hand the expression to the sniffer directly
/// @endcode

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "vigil/can/frame.hpp"
#include "vigil/can/node_map.hpp"
#include "vigil/error.hpp"
#include "vigil/expected.hpp"

namespace vigil::can {

/**
 * A filter expression: a tree of conditions on a frame, its direction and its node address.
 * Accepts every frame when default-constructed. A value type: copies share the (immutable)
 * tree. Building allocates: not RT-safe; thread-safe as any immutable value.
 */
class FilterExpr {
 public:
  /// What a node of the tree tests.
  enum class Kind : std::uint8_t {
    True,       ///< every frame
    False,      ///< no frame
    Bus,        ///< frame.bus in `values`
    Ids,        ///< frame.id in `values` (either id format)
    IdRange,    ///< values[0] <= frame.id <= values[1]
    IdMask,     ///< (frame.id & values[1]) == (values[0] & values[1])
    Nodes,      ///< mapped node in `values`
    NodeRange,  ///< values[0] <= mapped node <= values[1]
    Functions,  ///< mapped function (CANopen function code, J1939 PGN) in `values`
    Standard,   ///< 11-bit identifier
    Extended,   ///< 29-bit identifier
    Fd,         ///< CAN FD frame
    Remote,     ///< remote frame (RTR)
    Direction,  ///< direction == values[0] (0 = Rx, 1 = Tx)
    Payload,    ///< data byte values[0] exists and (byte & values[2]) == (values[1] & values[2])
    Not,        ///< children[0] does not hold
    All,        ///< every child holds (true when there is none)
    Any,        ///< at least one child holds (false when there is none)
  };

  struct Node;

  /// Accepts every frame.
  FilterExpr();
  /// A node built by the `match::` functions.
  explicit FilterExpr(std::shared_ptr<const Node> node);

  /// The root of the tree (never null).
  [[nodiscard]] const Node& node() const noexcept { return *node_; }
  /// True for the expression that accepts every frame (`True`, or `All` without children).
  [[nodiscard]] bool accepts_all() const noexcept;
  /// The expression in the syntax of `match::` calls, e.g.
  /// `all(bus(0), any(ids(0x181, 0x182), id_range(0x200, 0x27F)))`. Allocates.
  [[nodiscard]] std::string to_string() const;

  /// Both hold (flattened: `a && b && c` is one `All` of three).
  friend FilterExpr operator&&(const FilterExpr& a, const FilterExpr& b);
  /// Either holds (flattened like `&&`).
  friend FilterExpr operator||(const FilterExpr& a, const FilterExpr& b);
  /// Does not hold.
  friend FilterExpr operator!(const FilterExpr& a);

 private:
  std::shared_ptr<const Node> node_;
};

/// One node of a filter expression (immutable once built).
struct FilterExpr::Node {
  Kind kind = Kind::True;
  /// The node's operands (see `Kind`); sets are sorted and without duplicates.
  std::vector<std::uint32_t> values;
  /// The sub-expressions of Not, All and Any.
  std::vector<FilterExpr> children;
};

/// The conditions a filter is built from. Each returns a `FilterExpr`; none can fail (bad
/// operands, such as a range with lo > hi, are reported by `Filter::compile`).
namespace match {
/// Every frame.
[[nodiscard]] FilterExpr accept_all();
/// No frame.
[[nodiscard]] FilterExpr reject_all();
/// Frames on one of these buses (bus indices).
[[nodiscard]] FilterExpr bus(std::vector<std::uint8_t> buses);
/// Frames with one of these identifiers, standard or extended (combine with `standard()` or
/// `extended()` to tell 0x100 from 0x00000100).
[[nodiscard]] FilterExpr ids(std::vector<std::uint32_t> ids);
/// Frames with lo <= id <= hi.
[[nodiscard]] FilterExpr id_range(std::uint32_t lo, std::uint32_t hi);
/// Frames with (id & mask) == (value & mask), as SocketCAN's CAN_RAW_FILTER.
[[nodiscard]] FilterExpr id_mask(std::uint32_t value, std::uint32_t mask);
/// Frames whose node (through the sniffer's `NodeMap`) is one of these.
[[nodiscard]] FilterExpr nodes(std::vector<std::uint32_t> nodes);
/// Frames whose node is in [lo, hi].
[[nodiscard]] FilterExpr node_range(std::uint32_t lo, std::uint32_t hi);
/// Frames whose function (CANopen function code, J1939 PGN) is one of these.
[[nodiscard]] FilterExpr functions(std::vector<std::uint32_t> functions);
/// Frames with an 11-bit identifier.
[[nodiscard]] FilterExpr standard();
/// Frames with a 29-bit identifier.
[[nodiscard]] FilterExpr extended();
/// CAN FD frames.
[[nodiscard]] FilterExpr fd();
/// Remote frames.
[[nodiscard]] FilterExpr remote();
/// Frames read (Rx) or written (Tx).
[[nodiscard]] FilterExpr direction(Direction d);
/// Frames that have data byte `index` (0-based) and whose (byte & mask) == (value & mask), e.g.
/// a command byte: `payload_byte(0, 0x2F)` (an SDO download of one byte).
[[nodiscard]] FilterExpr payload_byte(std::uint32_t index, std::uint32_t value,
                                      std::uint32_t mask = 0xFF);
/// Every one of `parts` holds (true for none).
[[nodiscard]] FilterExpr all_of(std::vector<FilterExpr> parts);
/// At least one of `parts` holds (false for none).
[[nodiscard]] FilterExpr any_of(std::vector<FilterExpr> parts);
/// `part` does not hold.
[[nodiscard]] FilterExpr none_of(const FilterExpr& part);
}  // namespace match

/**
 * A compiled filter: a flat program evaluated on the CAN I/O thread.
 *
 * `matches()` is RT-safe: wait-free, allocation-free, lock-free, noexcept; its cost is linear
 * in the number of conditions, plus a binary search per id/node/function list (O(log n)).
 * A `Filter` is immutable after `compile`; share it between threads freely.
 */
class Filter {
 public:
  /// Deepest nesting of Not/All/Any accepted by `compile` (the evaluation stack's size).
  static constexpr std::size_t kMaxDepth = 32;

  /// Accepts every frame.
  Filter() = default;

  /// Compiles `expr`. Fails (EINVAL) naming the condition when an operand is out of range: a
  /// bus above 255, an identifier above 0x1FFFFFFF, a range with lo > hi, a payload index above
  /// 63 or a byte value or mask above 0xFF; or when it is nested deeper than kMaxDepth.
  /// Not RT-safe (allocates).
  [[nodiscard]] static expected<Filter, Error> compile(const FilterExpr& expr);

  /// Whether frame `f`, going in direction `d`, with node address `a` (from the sniffer's
  /// `NodeMap`), passes. RT-safe: yes (see the class comment). A filter that is an AND of
  /// simple conditions (buses, id ranges, an id mask, node ranges, the frame's format, the
  /// direction) is tested inline in one pass without a branch per condition; any other runs
  /// the program (`run`). Both give the same answer (tested on random filters and frames).
  [[nodiscard]] bool matches(const Frame& f, Direction d, NodeAddress a) const noexcept {
    if (conjunction_.active) return conjunction_.holds(f, d, a);
    return run(f, d, a);
  }

  /// The program, whatever the filter's shape (what `matches` does for a filter that is not a
  /// simple conjunction). RT-safe: yes.
  [[nodiscard]] bool run(const Frame& f, Direction d, NodeAddress a) const noexcept;

  /// True when `matches` takes the inline test (the filter is an AND of simple conditions).
  [[nodiscard]] bool is_simple_conjunction() const noexcept { return conjunction_.active; }

  /// Same, mapping the node with `map`. RT-safe: yes.
  [[nodiscard]] bool matches(const Frame& f, Direction d, const NodeMap& map) const noexcept {
    return matches(f, d, map.map(f));
  }

  /// True when the filter accepts every frame without looking at it.
  [[nodiscard]] bool accepts_all() const noexcept { return program_.empty(); }
  /// The source expression as text (`FilterExpr::to_string`), "true" for accept-all.
  [[nodiscard]] const std::string& text() const noexcept { return text_; }
  /// Number of instructions of the program (0 for accept-all).
  [[nodiscard]] std::size_t size() const noexcept { return program_.size(); }

  /// One instruction. Public for the compiler in filter.cpp only; not API.
  struct Instr {
    std::uint8_t op = 0;
    std::uint32_t a = 0;
    std::uint32_t b = 0;
    std::uint32_t c = 0;
  };

  /// A filter that is an AND of simple conditions, folded into one test (built by `compile`;
  /// inactive for any other filter). Public for the compiler in filter.cpp only; not API.
  struct Conjunction {
    static constexpr std::uint8_t kExtended = 1;
    static constexpr std::uint8_t kFd = 2;
    static constexpr std::uint8_t kRemote = 4;
    static constexpr std::uint8_t kTx = 8;
    bool active = false;
    bool never = false;          ///< contradictory conditions: no frame passes
    std::uint8_t flag_mask = 0;  ///< which of the bits above are tested
    std::uint8_t flag_want = 0;  ///< their required values
    std::uint32_t id_lo = 0;     ///< id - id_lo <= id_span (unsigned): id_lo <= id <= hi
    std::uint32_t id_span = ~std::uint32_t{0};
    std::uint32_t id_mask = 0;  ///< (id & id_mask) == id_value
    std::uint32_t id_value = 0;
    std::uint32_t node_lo = 0;  ///< as id_lo, for the mapped node
    std::uint32_t node_span = ~std::uint32_t{0};
    std::uint32_t buses[8] = {~0U, ~0U, ~0U, ~0U, ~0U, ~0U, ~0U, ~0U};  ///< bitmap of 256

    [[nodiscard]] bool holds(const Frame& f, Direction d, NodeAddress a) const noexcept {
      const unsigned flags = (f.extended ? kExtended : 0U) | (f.fd ? kFd : 0U) |
                             (f.rtr ? kRemote : 0U) | (d == Direction::Tx ? kTx : 0U);
      // Every condition evaluated, combined without branches: a few cycles whatever the frame.
      const bool bus = ((buses[f.bus / 32U] >> (f.bus % 32U)) & 1U) != 0;
      const bool id = f.id - id_lo <= id_span;
      const bool mask = (f.id & id_mask) == id_value;
      const bool node = a.node - node_lo <= node_span;
      const bool flag = (flags & flag_mask) == flag_want;
      return static_cast<bool>(static_cast<unsigned>(bus) & static_cast<unsigned>(id) &
                               static_cast<unsigned>(mask) & static_cast<unsigned>(node) &
                               static_cast<unsigned>(flag) & static_cast<unsigned>(!never));
    }
  };

 private:
  friend struct FilterCompiler;
  Conjunction conjunction_;
  std::vector<Instr> program_;
  std::vector<std::uint32_t> pool_;  // id/node/function sets (sorted) and bus bitmaps
  std::string text_ = "true";
};

}  // namespace vigil::can
