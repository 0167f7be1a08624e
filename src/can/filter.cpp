#include "vigil/can/filter.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <utility>

namespace vigil::can {

namespace {

using Kind = FilterExpr::Kind;

// The instructions of a compiled filter. Leaves push one bool; Not replaces the top; And/Or
// combine the top two.
enum class Op : std::uint8_t {
  True,
  False,
  Bus,        // a = pool offset of an 8-word bitmap of the 256 buses
  Ids,        // a = pool offset, b = count of a sorted set
  IdRange,    // a = lo, b = hi
  IdMask,     // a = value, b = mask
  Nodes,      // as Ids
  NodeRange,  // as IdRange
  Functions,  // as Ids
  Standard,
  Extended,
  Fd,
  Remote,
  Dir,      // a = 0 (Rx) or 1 (Tx)
  Payload,  // a = index, b = value, c = mask
  Not,
  And,
  Or,
};

std::shared_ptr<const FilterExpr::Node> make(Kind kind, std::vector<std::uint32_t> values = {},
                                             std::vector<FilterExpr> children = {}) {
  auto n = std::make_shared<FilterExpr::Node>();
  n->kind = kind;
  n->values = std::move(values);
  n->children = std::move(children);
  return n;
}

std::vector<std::uint32_t> sorted_unique(std::vector<std::uint32_t> v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

std::string hex_list(const std::vector<std::uint32_t>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i > 0) out += ", ";
    out += fmt::format("0x{:X}", v[i]);
  }
  return out;
}

std::string dec_list(const std::vector<std::uint32_t>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i > 0) out += ", ";
    out += fmt::format("{}", v[i]);
  }
  return out;
}

void append_text(std::string& out, const FilterExpr::Node& n) {
  const auto& v = n.values;
  switch (n.kind) {
    case Kind::True:
      out += "true";
      return;
    case Kind::False:
      out += "false";
      return;
    case Kind::Bus:
      out += "bus(" + dec_list(v) + ")";
      return;
    case Kind::Ids:
      out += "ids(" + hex_list(v) + ")";
      return;
    case Kind::IdRange:
      out += "id_range(" + hex_list(v) + ")";
      return;
    case Kind::IdMask:
      out += "id_mask(" + hex_list(v) + ")";
      return;
    case Kind::Nodes:
      out += "nodes(" + dec_list(v) + ")";
      return;
    case Kind::NodeRange:
      out += "node_range(" + dec_list(v) + ")";
      return;
    case Kind::Functions:
      out += "functions(" + hex_list(v) + ")";
      return;
    case Kind::Standard:
      out += "standard()";
      return;
    case Kind::Extended:
      out += "extended()";
      return;
    case Kind::Fd:
      out += "fd()";
      return;
    case Kind::Remote:
      out += "remote()";
      return;
    case Kind::Direction:
      out += v.empty() || v[0] == 0 ? "direction(rx)" : "direction(tx)";
      return;
    case Kind::Payload:
      out += fmt::format(
          "payload_byte({}, {})", v.empty() ? 0 : v[0],
          hex_list(std::vector<std::uint32_t>(v.begin() + (v.empty() ? 0 : 1), v.end())));
      return;
    case Kind::Not:
    case Kind::All:
    case Kind::Any:
      break;
  }
  out += n.kind == Kind::Not ? "not(" : n.kind == Kind::All ? "all(" : "any(";
  for (std::size_t i = 0; i < n.children.size(); ++i) {
    if (i > 0) out += ", ";
    append_text(out, n.children[i].node());
  }
  out += ")";
}

// `a op b`, flattening nested nodes of the same kind and dropping neutral elements.
FilterExpr combine(Kind kind, const FilterExpr& a, const FilterExpr& b) {
  const Kind neutral = kind == Kind::All ? Kind::True : Kind::False;
  const auto is_neutral = [&](const FilterExpr& e) {
    return e.node().kind == neutral || (e.node().kind == kind && e.node().children.empty());
  };
  if (is_neutral(a)) return b;
  if (is_neutral(b)) return a;
  std::vector<FilterExpr> parts;
  for (const FilterExpr* e : {&a, &b}) {
    if (e->node().kind == kind) {
      parts.insert(parts.end(), e->node().children.begin(), e->node().children.end());
    } else {
      parts.push_back(*e);
    }
  }
  return FilterExpr(make(kind, {}, std::move(parts)));
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// FilterExpr

FilterExpr::FilterExpr() : node_(make(Kind::True)) {}

FilterExpr::FilterExpr(std::shared_ptr<const Node> node)
    : node_(node ? std::move(node) : make(Kind::True)) {}

bool FilterExpr::accepts_all() const noexcept {
  return node_->kind == Kind::True || (node_->kind == Kind::All && node_->children.empty());
}

std::string FilterExpr::to_string() const {
  std::string out;
  append_text(out, *node_);
  return out;
}

FilterExpr operator&&(const FilterExpr& a, const FilterExpr& b) { return combine(Kind::All, a, b); }

FilterExpr operator||(const FilterExpr& a, const FilterExpr& b) { return combine(Kind::Any, a, b); }

FilterExpr operator!(const FilterExpr& a) { return FilterExpr(make(Kind::Not, {}, {a})); }

namespace match {
FilterExpr accept_all() { return FilterExpr(make(Kind::True)); }
FilterExpr reject_all() { return FilterExpr(make(Kind::False)); }
FilterExpr bus(std::vector<std::uint8_t> buses) {
  return FilterExpr(make(Kind::Bus, sorted_unique({buses.begin(), buses.end()})));
}
FilterExpr ids(std::vector<std::uint32_t> ids) {
  return FilterExpr(make(Kind::Ids, sorted_unique(std::move(ids))));
}
FilterExpr id_range(std::uint32_t lo, std::uint32_t hi) {
  return FilterExpr(make(Kind::IdRange, {lo, hi}));
}
FilterExpr id_mask(std::uint32_t value, std::uint32_t mask) {
  return FilterExpr(make(Kind::IdMask, {value, mask}));
}
FilterExpr nodes(std::vector<std::uint32_t> nodes) {
  return FilterExpr(make(Kind::Nodes, sorted_unique(std::move(nodes))));
}
FilterExpr node_range(std::uint32_t lo, std::uint32_t hi) {
  return FilterExpr(make(Kind::NodeRange, {lo, hi}));
}
FilterExpr functions(std::vector<std::uint32_t> functions) {
  return FilterExpr(make(Kind::Functions, sorted_unique(std::move(functions))));
}
FilterExpr standard() { return FilterExpr(make(Kind::Standard)); }
FilterExpr extended() { return FilterExpr(make(Kind::Extended)); }
FilterExpr fd() { return FilterExpr(make(Kind::Fd)); }
FilterExpr remote() { return FilterExpr(make(Kind::Remote)); }
FilterExpr direction(Direction d) {
  return FilterExpr(make(Kind::Direction, {d == Direction::Tx ? 1U : 0U}));
}
FilterExpr payload_byte(std::uint32_t index, std::uint32_t value, std::uint32_t mask) {
  return FilterExpr(make(Kind::Payload, {index, value, mask}));
}
FilterExpr all_of(std::vector<FilterExpr> parts) {
  return FilterExpr(make(Kind::All, {}, std::move(parts)));
}
FilterExpr any_of(std::vector<FilterExpr> parts) {
  return FilterExpr(make(Kind::Any, {}, std::move(parts)));
}
FilterExpr none_of(const FilterExpr& part) { return !part; }
}  // namespace match

// ---------------------------------------------------------------------------------------------
// Filter

struct FilterCompiler {
  Filter& out;
  std::size_t sp = 0;
  std::size_t max_sp = 0;
  std::string error;

  void emit(Op op, std::uint32_t a = 0, std::uint32_t b = 0, std::uint32_t c = 0) {
    out.program_.push_back({static_cast<std::uint8_t>(op), a, b, c});
    switch (op) {
      case Op::Not:
        break;
      case Op::And:
      case Op::Or:
        --sp;
        break;
      default:
        ++sp;
        max_sp = std::max(max_sp, sp);
        break;
    }
  }

  bool fail(const FilterExpr::Node& n, std::string_view why) {
    if (error.empty()) {
      std::string text;
      append_text(text, n);
      error = fmt::format("filter condition {}: {}", text, why);
    }
    return false;
  }

  std::uint32_t add_set(const std::vector<std::uint32_t>& v) {
    const auto offset = static_cast<std::uint32_t>(out.pool_.size());
    out.pool_.insert(out.pool_.end(), v.begin(), v.end());
    return offset;
  }

  bool range_ok(const FilterExpr::Node& n, std::uint32_t limit, const char* what) {
    if (n.values.size() != 2) return fail(n, "needs two operands");
    for (const std::uint32_t v : n.values) {
      if (v > limit) return fail(n, fmt::format("{} 0x{:X} is above 0x{:X}", what, v, limit));
    }
    if (n.values[0] > n.values[1]) return fail(n, "lo is above hi");
    return true;
  }

  // A sorted set operand: its offset in the pool, and its size.
  void emit_set(Op op, const std::vector<std::uint32_t>& set) {
    emit(op, add_set(set), static_cast<std::uint32_t>(set.size()));
  }

  // The tree: not(), all(), any() and their conditions, depth first (postfix).
  bool compile(const FilterExpr::Node& n, std::size_t depth) {
    if (depth > Filter::kMaxDepth) {
      return fail(n, fmt::format("nested more than {} levels deep", Filter::kMaxDepth));
    }
    if (n.kind == Kind::Not) {
      if (n.children.size() != 1) return fail(n, "not() takes one condition");
      if (!compile(n.children[0].node(), depth + 1)) return false;
      emit(Op::Not);
      return true;
    }
    if (n.kind == Kind::All || n.kind == Kind::Any) {
      const bool all = n.kind == Kind::All;
      if (n.children.empty()) {
        emit(all ? Op::True : Op::False);
        return true;
      }
      for (std::size_t i = 0; i < n.children.size(); ++i) {
        if (!compile(n.children[i].node(), depth + 1)) return false;
        if (i > 0) emit(all ? Op::And : Op::Or);
      }
      return true;
    }
    return condition(n);
  }

  // One condition on a frame (a leaf of the tree), its operands checked.
  bool condition(const FilterExpr::Node& n) {
    const auto& v = n.values;
    switch (n.kind) {
      case Kind::True:
        emit(Op::True);
        return true;
      case Kind::False:
        emit(Op::False);
        return true;
      case Kind::Bus: {
        std::array<std::uint32_t, 8> bits{};
        for (const std::uint32_t b : v) {
          if (b > 255) return fail(n, fmt::format("bus {} is above 255", b));
          bits[b / 32] |= 1U << (b % 32);
        }
        emit(Op::Bus, add_set({bits.begin(), bits.end()}));
        return true;
      }
      case Kind::Ids:
        for (const std::uint32_t id : v) {
          if (id > kMaxExtendedId) {
            return fail(n, fmt::format("identifier 0x{:X} is above 0x1FFFFFFF", id));
          }
        }
        emit_set(Op::Ids, sorted_unique(v));  // nodes built by hand may hold duplicates
        return true;
      case Kind::IdRange:
        if (!range_ok(n, kMaxExtendedId, "identifier")) return false;
        emit(Op::IdRange, v[0], v[1]);
        return true;
      case Kind::IdMask:
        if (v.size() != 2) return fail(n, "needs a value and a mask");
        if (v[0] > kMaxExtendedId || v[1] > kMaxExtendedId) {
          return fail(n, "value and mask must be at most 0x1FFFFFFF");
        }
        emit(Op::IdMask, v[0] & v[1], v[1]);
        return true;
      case Kind::Nodes:
        emit_set(Op::Nodes, sorted_unique(v));
        return true;
      case Kind::NodeRange:
        if (!range_ok(n, ~std::uint32_t{0}, "node")) return false;
        emit(Op::NodeRange, v[0], v[1]);
        return true;
      case Kind::Functions:
        emit_set(Op::Functions, sorted_unique(v));
        return true;
      case Kind::Standard:
        emit(Op::Standard);
        return true;
      case Kind::Extended:
        emit(Op::Extended);
        return true;
      case Kind::Fd:
        emit(Op::Fd);
        return true;
      case Kind::Remote:
        emit(Op::Remote);
        return true;
      case Kind::Direction:
        if (v.size() != 1 || v[0] > 1) return fail(n, "direction must be rx (0) or tx (1)");
        emit(Op::Dir, v[0]);
        return true;
      case Kind::Payload:
        if (v.size() != 3) return fail(n, "needs an index, a value and a mask");
        if (v[0] >= kMaxFdDataLength) {
          return fail(n, fmt::format("byte index {} is above 63", v[0]));
        }
        if (v[1] > 0xFF || v[2] > 0xFF) return fail(n, "value and mask must be at most 0xFF");
        emit(Op::Payload, v[0], v[1] & v[2], v[2]);
        return true;
      case Kind::Not:
      case Kind::All:
      case Kind::Any:
        break;  // compile()'s
    }
    return fail(n, "unknown condition");
  }
};

namespace {

// A program of simple conditions joined by And only (postfix: whatever the tree's shape, it is
// then the AND of all its conditions), folded into one Conjunction; inactive for any other.
Filter::Conjunction fold_conjunction(const std::vector<Filter::Instr>& program,
                                     const std::vector<std::uint32_t>& pool) {
  using C = Filter::Conjunction;
  C c;
  if (program.empty()) return c;
  std::uint32_t id_hi = ~std::uint32_t{0};
  std::uint32_t node_hi = ~std::uint32_t{0};
  const auto want = [&c](std::uint8_t bit, bool value) {
    const auto v = static_cast<std::uint8_t>(value ? bit : 0);
    if ((c.flag_mask & bit) != 0 && (c.flag_want & bit) != v) c.never = true;
    c.flag_mask = static_cast<std::uint8_t>(c.flag_mask | bit);
    c.flag_want = static_cast<std::uint8_t>(c.flag_want | v);
  };
  for (const Filter::Instr& in : program) {
    switch (static_cast<Op>(in.op)) {
      case Op::True:
      case Op::And:
        break;
      case Op::False:
        c.never = true;
        break;
      case Op::Bus:
        for (std::uint32_t w = 0; w < 8; ++w) c.buses[w] &= pool[in.a + w];
        break;
      case Op::IdRange:
        c.id_lo = std::max(c.id_lo, in.a);
        id_hi = std::min(id_hi, in.b);
        break;
      case Op::NodeRange:
        c.node_lo = std::max(c.node_lo, in.a);
        node_hi = std::min(node_hi, in.b);
        break;
      case Op::IdMask:
        // (id & m1) == v1 and (id & m2) == v2: (id & (m1 | m2)) == (v1 | v2) when v1 and v2
        // agree where both masks test; no id otherwise.
        if ((c.id_value & in.b) != (in.a & c.id_mask)) c.never = true;
        c.id_mask |= in.b;
        c.id_value |= in.a;
        break;
      case Op::Standard:
        want(C::kExtended, false);
        break;
      case Op::Extended:
        want(C::kExtended, true);
        break;
      case Op::Fd:
        want(C::kFd, true);
        break;
      case Op::Remote:
        want(C::kRemote, true);
        break;
      case Op::Dir:
        if (in.a > 1) c.never = true;
        want(C::kTx, in.a == 1);
        break;
      case Op::Ids:
      case Op::Nodes:
      case Op::Functions:
      case Op::Payload:
      case Op::Not:
      case Op::Or:
        return C{};  // not a simple conjunction: the program runs
    }
  }
  if (c.id_lo > id_hi || c.node_lo > node_hi) c.never = true;
  c.id_span = c.id_lo > id_hi ? 0 : id_hi - c.id_lo;
  c.node_span = c.node_lo > node_hi ? 0 : node_hi - c.node_lo;
  c.active = true;
  return c;
}

}  // namespace

expected<Filter, Error> Filter::compile(const FilterExpr& expr) {
  Filter f;
  if (expr.accepts_all()) return f;  // empty program: the sniffer's fast path
  FilterCompiler c{f, 0, 0, {}};
  if (!c.compile(expr.node(), 0)) return unexpected(Error(EINVAL, std::move(c.error)));
  if (c.max_sp > kMaxDepth + 1) {  // cannot happen with the depth check; the stack's bound
    return unexpected(
        Error(EINVAL, fmt::format("filter nested more than {} levels deep", kMaxDepth)));
  }
  f.text_ = expr.to_string();
  f.conjunction_ = fold_conjunction(f.program_, f.pool_);
  return f;
}

bool Filter::run(const Frame& f, Direction d, NodeAddress a) const noexcept {
  if (program_.empty()) return true;
  std::array<bool, kMaxDepth + 1> stack;  // compile() bounds the depth
  std::size_t sp = 0;
  const auto in_set = [&](std::uint32_t offset, std::uint32_t count, std::uint32_t x) noexcept {
    const std::uint32_t* first = pool_.data() + offset;
    return std::binary_search(first, first + count, x);
  };
  for (const Instr& in : program_) {
    bool r = false;
    switch (static_cast<Op>(in.op)) {
      case Op::True:
        r = true;
        break;
      case Op::False:
        r = false;
        break;
      case Op::Bus:
        r = ((pool_[in.a + f.bus / 32U] >> (f.bus % 32U)) & 1U) != 0;
        break;
      case Op::Ids:
        r = in_set(in.a, in.b, f.id);
        break;
      case Op::IdRange:
        r = f.id >= in.a && f.id <= in.b;
        break;
      case Op::IdMask:
        r = (f.id & in.b) == in.a;
        break;
      case Op::Nodes:
        r = in_set(in.a, in.b, a.node);
        break;
      case Op::NodeRange:
        r = a.node >= in.a && a.node <= in.b;
        break;
      case Op::Functions:
        r = in_set(in.a, in.b, a.function);
        break;
      case Op::Standard:
        r = !f.extended;
        break;
      case Op::Extended:
        r = f.extended;
        break;
      case Op::Fd:
        r = f.fd;
        break;
      case Op::Remote:
        r = f.rtr;
        break;
      case Op::Dir:
        r = (d == Direction::Tx ? 1U : 0U) == in.a;
        break;
      case Op::Payload:
        r = in.a < f.data_size() && (f.data[in.a] & in.c) == in.b;
        break;
      case Op::Not:
        stack[sp - 1] = !stack[sp - 1];
        continue;
      case Op::And:
        --sp;
        stack[sp - 1] = stack[sp - 1] && stack[sp];
        continue;
      case Op::Or:
        --sp;
        stack[sp - 1] = stack[sp - 1] || stack[sp];
        continue;
    }
    stack[sp++] = r;
  }
  return stack[0];
}

}  // namespace vigil::can
