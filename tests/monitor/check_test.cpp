#include "vigil/monitor/check.hpp"

#include <catch2/catch.hpp>
#include <stdexcept>

using namespace vigil;
using namespace vigil::monitor;

namespace {

// A plain class: satisfies the Check concept without deriving from anything.
struct PlainCheck {
  [[nodiscard]] std::string_view name() const { return "plain"; }
  void run(const CheckInput& in, Report& out) {
    ++runs;
    out.add("plain.cycles", std::to_string(in.component.counters.cycles));
    if (in.component.counters.cycles > limit) out.merge(StatusLevel::Warn, "too many cycles");
  }
  std::uint64_t limit = 10;
  int runs = 0;
};

// The runtime base, for checks chosen at run time.
class DerivedCheck final : public CheckBase {
 public:
  [[nodiscard]] std::string_view name() const override { return "derived"; }
  void run(const CheckInput&, Report& out) override { out.merge(StatusLevel::Ok, "derived ran"); }
};

struct ThrowingCheck {
  [[nodiscard]] std::string_view name() const { return "throwing"; }
  void run(const CheckInput&, Report&) { throw std::runtime_error("broken"); }
};

struct NotACheck {
  void run(const CheckInput&, Report&) {}  // no name()
};
struct WrongRun {
  [[nodiscard]] std::string_view name() const { return "x"; }
  int run(const CheckInput&, Report&) { return 0; }  // must return void
};

}  // namespace

TEST_CASE("The Check concept accepts plain classes and CheckBase", "[monitor][check]") {
  STATIC_REQUIRE(Check<PlainCheck>);
  STATIC_REQUIRE(Check<DerivedCheck>);
  STATIC_REQUIRE(Check<CheckBase>);
  STATIC_REQUIRE_FALSE(Check<NotACheck>);
  STATIC_REQUIRE_FALSE(Check<WrongRun>);
  STATIC_REQUIRE_FALSE(Check<int>);
}

TEST_CASE("A CheckList runs its checks in order and exposes what it added", "[monitor][check]") {
  supervisor::ComponentSnapshot s;
  s.counters.cycles = 11;
  const Thresholds t;
  const Window w;
  CheckList list;
  PlainCheck& plain = list.add<PlainCheck>();
  plain.limit = 10;
  list.add<DerivedCheck>();
  list.add(PlainCheck{.limit = 100, .runs = 0});
  REQUIRE(list.size() == 3);
  CHECK(list.names() == std::vector<std::string>{"plain", "derived", "plain"});

  Report r;
  list.run(CheckInput{s, t, w, 0, -1}, r);
  CHECK(plain.runs == 1);
  CHECK(r.status.level() == StatusLevel::Warn);
  CHECK(r.status.summary() == "too many cycles; derived ran");
  CHECK(r.values.size() == 2);
  CHECK(*r.value("plain.cycles") == "11");

  CHECK(list.remove("plain") == 2);
  CHECK(list.names() == std::vector<std::string>{"derived"});
}

TEST_CASE("A check that throws makes the component ERROR, and the others still run",
          "[monitor][check]") {
  supervisor::ComponentSnapshot s;
  const Thresholds t;
  const Window w;
  CheckList list;
  list.add<ThrowingCheck>();
  list.add(std::make_unique<DerivedCheck>());
  Report r;
  list.run(CheckInput{s, t, w, 0, -1}, r);
  CHECK(r.status.level() == StatusLevel::Error);
  CHECK(r.status.summary() == "check throwing failed: broken; derived ran");
}
