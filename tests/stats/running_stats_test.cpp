#include "vigil/supervisor/running_stats.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

using vigil::Nanos;
using vigil::StatsSummary;
using vigil::supervisor::RunningStats;

// ---- A counting replacement of the global operator new/delete (not malloc), for the whole test
// binary. It counts only while `g_counting` is set, so Catch2's own allocations do not matter.
namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::uint64_t> g_allocations{0};

void* counted_alloc(std::size_t size) noexcept {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
  }
  return std::malloc(size == 0 ? 1 : size);
}

// Out of line so that GCC does not pair an inlined free() with the new-expression at the call
// site (-Wmismatched-new-delete cannot know that this operator new calls malloc).
[[gnu::noinline]] void counted_free(void* p) noexcept { std::free(p); }
}  // namespace

void* operator new(std::size_t size) {
  if (void* p = counted_alloc(size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
  if (void* p = counted_alloc(size)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return counted_alloc(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return counted_alloc(size);
}
void operator delete(void* p) noexcept { counted_free(p); }
void operator delete[](void* p) noexcept { counted_free(p); }
void operator delete(void* p, std::size_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { counted_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { counted_free(p); }

namespace {

static_assert(std::is_trivially_copyable_v<RunningStats>);
static_assert(std::is_trivially_copyable_v<StatsSummary>);
static_assert(sizeof(StatsSummary) == 80);
static_assert(sizeof(RunningStats) == 9312);
static_assert(noexcept(std::declval<RunningStats&>().add(Nanos{1})));

// Nearest rank on sorted samples, negative values clamped to 0 (as the histogram counts them).
Nanos exact_quantile(const std::vector<Nanos>& sorted, double q) {
  const auto n = sorted.size();
  auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(n)));
  rank = std::clamp<std::size_t>(rank, 1, n);
  return std::max<Nanos>(sorted[rank - 1], 0);
}

std::vector<Nanos> make_data(const std::string& kind, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Nanos> v;
  v.reserve(n);
  if (kind == "uniform") {
    std::uniform_int_distribution<Nanos> d(0, 5'000'000);
    for (std::size_t i = 0; i < n; ++i) v.push_back(d(rng));
  } else if (kind == "exponential") {
    std::exponential_distribution<double> d(1.0 / 200'000.0);
    for (std::size_t i = 0; i < n; ++i) v.push_back(static_cast<Nanos>(d(rng)));
  } else if (kind == "bimodal") {
    std::normal_distribution<double> d(250'000.0, 5'000.0);
    for (std::size_t i = 0; i + 3 < n; ++i) v.push_back(static_cast<Nanos>(d(rng)));
    for (Nanos s : {9'000'000, 9'100'000, 9'200'000}) v.push_back(s);
    std::shuffle(v.begin(), v.end(), rng);
  } else {  // constant
    v.assign(n, 1'000'001);
  }
  return v;
}

// Within the documented bound of the exact nearest-rank quantile, and never above max.
void check_percentile(Nanos got, const std::vector<Nanos>& sorted, double q) {
  const Nanos exact = exact_quantile(sorted, q);
  INFO("q = " << q << ", exact = " << exact << ", reported = " << got);
  CHECK(got >= exact);
  CHECK(got - exact <= (exact >> 5));
  CHECK(got <= sorted.back());
  if (exact < 64) CHECK(got == exact);
}

double reference_ewma(const std::vector<Nanos>& data, double alpha) {
  double e = static_cast<double>(data.front());
  for (std::size_t i = 1; i < data.size(); ++i)
    e = (1 - alpha) * e + alpha * static_cast<double>(data[i]);
  return e;
}

}  // namespace

TEST_CASE("RunningStats without samples reports count 0 and all values 0", "[stats][running]") {
  const RunningStats s;
  CHECK(s.count() == 0);
  CHECK(s.last() == 0);
  CHECK(s.min() == 0);
  CHECK(s.max() == 0);
  CHECK(s.mean() == 0.0);
  CHECK(s.ewma() == 0.0);
  CHECK(s.value_at_quantile(0.5) == 0);
  CHECK(s.summary() == StatsSummary{});
  CHECK(s.ewma_weight() == RunningStats::kDefaultEwmaWeight);
}

TEST_CASE("RunningStats with one sample reports exactly that sample everywhere",
          "[stats][running]") {
  for (Nanos v : {Nanos{0}, Nanos{5}, Nanos{1'234'567}, Nanos{-3}, (Nanos{1} << 40) + 1}) {
    RunningStats s;
    s.add(v);
    const StatsSummary sum = s.summary();
    INFO("sample " << v);
    CHECK(sum == StatsSummary{.count = 1,
                              .last = v,
                              .min = v,
                              .max = v,
                              .mean = static_cast<double>(v),
                              .ewma = static_cast<double>(v),
                              .p50 = v,
                              .p90 = v,
                              .p99 = v,
                              .p999 = v});
    CHECK(s.value_at_quantile(0.0) == v);
    CHECK(s.value_at_quantile(1.0) == v);
  }
}

TEST_CASE("RunningStats count, last, min, max and mean are exact", "[stats][running]") {
  const std::string kind =
      GENERATE(as<std::string>{}, "uniform", "exponential", "bimodal", "constant");
  const auto data = make_data(kind, 100'000, 5);
  RunningStats s;
  Nanos sum = 0;
  for (Nanos v : data) {
    s.add(v);
    sum += v;
  }
  INFO(kind);
  CHECK(s.count() == data.size());
  CHECK(s.last() == data.back());
  CHECK(s.min() == *std::min_element(data.begin(), data.end()));
  CHECK(s.max() == *std::max_element(data.begin(), data.end()));
  // sum fits in int64 here; the reference rounds twice, as the implementation does.
  CHECK(s.mean() == static_cast<double>(sum) / static_cast<double>(data.size()));
}

TEST_CASE("RunningStats mean stays exact when the sum exceeds 64 bits or is negative",
          "[stats][running]") {
  constexpr Nanos kMax = std::numeric_limits<Nanos>::max();
  constexpr Nanos kMin = std::numeric_limits<Nanos>::min();
  RunningStats big;
  for (int i = 0; i < 1000; ++i) big.add(kMax);
  CHECK(big.mean() == static_cast<double>(kMax));
  big.add(kMin);
  big.add(kMin);  // sum = 998 * kMax - 2: mean = kMax * 998 / 1002 - 2 / 1002
  CHECK(big.mean() == Approx(static_cast<double>(kMax) * (998.0 / 1002.0)).epsilon(1e-15));

  RunningStats neg;
  for (Nanos v : {-5, -7, 3}) neg.add(v);
  CHECK(neg.mean() == -3.0);
  CHECK(neg.min() == -7);
  CHECK(neg.max() == 3);

  RunningStats small_neg;  // a small negative sum is stored as hi = -1, lo ~ 2^64
  small_neg.add(-1);
  CHECK(small_neg.mean() == -1.0);

  RunningStats cancel;  // the sum crosses +-2^63 and returns
  cancel.add(kMax);
  cancel.add(kMax);
  cancel.add(kMin);
  cancel.add(kMin);
  cancel.add(8);
  CHECK(cancel.mean() == Approx(6.0 / 5.0).epsilon(1e-15));
}

TEST_CASE("RunningStats EWMA matches a reference loop for several weights", "[stats][running]") {
  const double alpha = GENERATE(0.001, 0.01, 0.125, 0.5, 0.9, 1.0);
  const auto data = make_data("exponential", 10'000, 9);
  RunningStats s;
  REQUIRE(s.set_ewma_weight(alpha));
  CHECK(s.ewma_weight() == alpha);
  for (Nanos v : data) s.add(v);
  INFO("alpha = " << alpha);
  CHECK(s.ewma() == Approx(reference_ewma(data, alpha)).epsilon(1e-12));
  if (alpha == 1.0) CHECK(s.ewma() == static_cast<double>(data.back()));
}

TEST_CASE("RunningStats EWMA starts at the first sample and follows a step", "[stats][running]") {
  RunningStats s;
  REQUIRE(s.set_ewma_weight(0.5));
  s.add(100);
  CHECK(s.ewma() == 100.0);
  s.add(200);
  CHECK(s.ewma() == 150.0);
  s.add(200);
  CHECK(s.ewma() == 175.0);
}

TEST_CASE("RunningStats set_ewma_weight accepts 0 < alpha <= 1 and rejects everything else",
          "[stats][running]") {
  RunningStats s;
  for (double bad :
       {0.0, -0.1, 1.0000001, 2.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    CHECK_FALSE(s.set_ewma_weight(bad));
    CHECK(s.ewma_weight() == RunningStats::kDefaultEwmaWeight);
  }
  CHECK(s.set_ewma_weight(1.0));
  CHECK(s.set_ewma_weight(1e-9));
  CHECK(s.ewma_weight() == 1e-9);
}

TEST_CASE("RunningStats percentiles are within 1/32 of the exact nearest-rank percentile",
          "[stats][running]") {
  const std::string kind =
      GENERATE(as<std::string>{}, "uniform", "exponential", "bimodal", "constant");
  const std::size_t n = GENERATE(1, 2, 7, 1000, 50'000);
  INFO(kind << ", n = " << n);
  auto data = make_data(kind, n, 17 + n);
  RunningStats s;
  for (Nanos v : data) s.add(v);
  std::sort(data.begin(), data.end());
  const StatsSummary sum = s.summary();
  check_percentile(sum.p50, data, 0.5);
  check_percentile(sum.p90, data, 0.9);
  check_percentile(sum.p99, data, 0.99);
  check_percentile(sum.p999, data, 0.999);
  for (double q : {0.0, 0.001, 0.25, 0.75, 0.95, 0.9999, 1.0}) {
    check_percentile(s.value_at_quantile(q), data, q);
  }
  CHECK(s.value_at_quantile(1.0) == data.back());  // clamped to the exact max
}

TEST_CASE("RunningStats p99.9 of 1000 samples shows a 3-sample spike, p99 does not",
          "[stats][running]") {
  RunningStats s;
  for (Nanos v : make_data("bimodal", 1000, 4)) s.add(v);
  const StatsSummary sum = s.summary();
  CHECK(sum.p99 < 1'000'000);
  CHECK(sum.p999 >= 9'100'000);  // rank 999: the second spike sample
  CHECK(sum.max == 9'200'000);
}

TEST_CASE("RunningStats percentiles of overflowed samples report the exact max",
          "[stats][running]") {
  RunningStats s;
  s.add(60);
  s.add(Nanos{1} << 45);
  s.add(Nanos{1} << 46);
  CHECK(s.histogram().overflow_count() == 2);
  CHECK(s.value_at_quantile(0.0) == 60);
  CHECK(s.value_at_quantile(0.5) == Nanos{1} << 46);  // beyond 2^40: only max is known
  CHECK(s.summary().p999 == Nanos{1} << 46);
}

TEST_CASE("RunningStats counts negative samples as 0 in the percentiles", "[stats][running]") {
  RunningStats s;
  s.add(-10);
  s.add(-20);
  s.add(30);
  CHECK(s.histogram().negative_count() == 2);
  CHECK(s.min() == -20);
  CHECK(s.value_at_quantile(0.5) == 0);
  CHECK(s.value_at_quantile(1.0) == 30);
}

TEST_CASE("RunningStats merge equals adding every sample to one, in order", "[stats][running]") {
  const double alpha = GENERATE(0.05, 0.125, 1.0);
  const auto a_data = make_data("exponential", 4000, 21);
  const auto b_data = make_data("bimodal", 2500, 22);
  RunningStats a, b, all;
  for (RunningStats* s : {&a, &b, &all}) REQUIRE(s->set_ewma_weight(alpha));
  for (Nanos v : a_data) {
    a.add(v);
    all.add(v);
  }
  for (Nanos v : b_data) {
    b.add(v);
    all.add(v);
  }
  a.merge(b);
  const StatsSummary got = a.summary();
  const StatsSummary want = all.summary();
  INFO("alpha = " << alpha);
  CHECK(got.count == want.count);
  CHECK(got.last == want.last);
  CHECK(got.min == want.min);
  CHECK(got.max == want.max);
  CHECK(got.mean == want.mean);
  CHECK(got.ewma == Approx(want.ewma).epsilon(1e-12));
  CHECK(got.p50 == want.p50);
  CHECK(got.p90 == want.p90);
  CHECK(got.p99 == want.p99);
  CHECK(got.p999 == want.p999);

  // A short b, so the EWMA of a still shows through.
  RunningStats c, d, cd;
  for (RunningStats* s : {&c, &d, &cd}) REQUIRE(s->set_ewma_weight(alpha));
  for (Nanos v : {1000, 2000, 3000}) {
    c.add(v);
    cd.add(v);
  }
  for (Nanos v : {50, 70}) {
    d.add(v);
    cd.add(v);
  }
  c.merge(d);
  CHECK(c.ewma() == Approx(cd.ewma()).epsilon(1e-12));
  CHECK(c.summary().last == 70);
}

TEST_CASE("RunningStats merge with an empty side keeps the other and this weight",
          "[stats][running]") {
  RunningStats full;
  for (Nanos v : {5, 9, 7}) full.add(v);
  RunningStats empty;
  REQUIRE(empty.set_ewma_weight(0.5));

  RunningStats copy = full;
  copy.merge(empty);
  CHECK(copy.summary() == full.summary());

  empty.merge(full);
  CHECK(empty.summary() == full.summary());
  CHECK(empty.ewma_weight() == 0.5);
}

TEST_CASE("RunningStats reset forgets the samples and keeps the EWMA weight", "[stats][running]") {
  RunningStats s;
  REQUIRE(s.set_ewma_weight(0.25));
  for (Nanos v : make_data("uniform", 1000, 30)) s.add(v);
  s.reset();
  CHECK(s.summary() == StatsSummary{});
  CHECK(s.histogram().count() == 0);
  CHECK(s.ewma_weight() == 0.25);
  s.add(40);
  s.add(80);
  CHECK(s.min() == 40);
  CHECK(s.ewma() == 50.0);
}

TEST_CASE("RunningStats add, summary and merge do not allocate", "[stats][running][alloc]") {
  // The counter works: a direct call cannot be elided as a new-expression can.
  g_allocations = 0;
  g_counting = true;
  void* volatile probe = ::operator new(16);
  g_counting = false;
  ::operator delete(probe);
  REQUIRE(g_allocations.load() == 1);

  auto stats = std::make_unique<RunningStats>();
  auto other = std::make_unique<RunningStats>();
  auto hist = std::make_unique<RunningStats::Histogram>();
  std::mt19937_64 rng(77);
  std::vector<Nanos> data(1'000'000);
  for (Nanos& v : data) v = static_cast<Nanos>(rng() >> 36);  // up to 2^28 ns
  other->add(5);

  g_allocations = 0;
  g_counting = true;
  for (Nanos v : data) stats->add(v);
  for (Nanos v : data) hist->add(v);
  stats->merge(*other);
  const StatsSummary sum = stats->summary();
  stats->reset();
  g_counting = false;

  CHECK(g_allocations.load() == 0);
  CHECK(sum.count == 1'000'001);
  CHECK(hist->count() == 1'000'000);
}

// ---- CompactRunningStats: what the supervisor keeps per component -------------------------------

TEST_CASE(
    "CompactRunningStats gives exactly RunningStats' values, within 1/32 of exact percentiles",
    "[stats][running][compact]") {
  const std::string kind =
      GENERATE(as<std::string>{}, "uniform", "exponential", "bimodal", "constant");
  const std::size_t n = GENERATE(1, 7, 1000, 50'000);
  INFO(kind << ", n = " << n);
  auto data = make_data(kind, n, 23 + n);
  vigil::supervisor::CompactRunningStats c;
  auto fixed = std::make_unique<RunningStats>();
  for (Nanos v : data) {
    c.add(v);
    fixed->add(v);
  }
  const StatsSummary sum = c.summary();
  CHECK(sum == fixed->summary());
  std::sort(data.begin(), data.end());
  check_percentile(sum.p50, data, 0.5);
  check_percentile(sum.p90, data, 0.9);
  check_percentile(sum.p99, data, 0.99);
  check_percentile(sum.p999, data, 0.999);
}

TEST_CASE("CompactRunningStats allocates while its range grows, then never",
          "[stats][running][compact][alloc]") {
  vigil::supervisor::CompactRunningStats s;
  std::mt19937_64 rng(78);
  std::uniform_int_distribution<Nanos> cycle(40'000, 70'000);  // two octaves
  g_allocations = 0;
  g_counting = true;
  for (int i = 0; i < 1000; ++i) s.add(cycle(rng));
  g_counting = false;
  CHECK(g_allocations.load() >= 1);
  CHECK(g_allocations.load() <= 2);  // one chunk, then the second octave
  g_allocations = 0;
  g_counting = true;
  for (int i = 0; i < 1'000'000; ++i) s.add(cycle(rng));
  const StatsSummary sum = s.summary();
  g_counting = false;
  CHECK(g_allocations.load() == 0);
  CHECK(sum.count == 1'001'000);
  CHECK(s.histogram().heap_bytes() == 2 * 256);
}

TEST_CASE("Statistics given runs of samples, several at once, equal those given each sample",
          "[stats][running]") {
  // add_all interleaves the statistics' EWMA chains and histograms: the result must be the
  // same bit for bit (same operations, same order per statistic), from empty or not, whatever
  // the lengths of the runs.
  // Some rounds bring values a 64-bit block sum could not hold (add_all sums blocks of values
  // within +-2^56 in one word, and sums any other block value by value), some values beyond
  // the histograms' range (their checks are skipped only for runs known to be within it).
  std::mt19937_64 rng(21);
  std::uniform_int_distribution<vigil::Nanos> value(-1'000, 5'000'000);
  std::uniform_int_distribution<vigil::Nanos> huge(std::numeric_limits<vigil::Nanos>::min() / 2,
                                                   std::numeric_limits<vigil::Nanos>::max() / 2);
  for (int round = 0; round < 80; ++round) {
    const int extreme = round % 4;  // 0: none; 1: now and then; 2: often; 3: the 2^56 edges
    const auto draw = [&] {
      if (extreme == 1 && rng() % 40 == 0) return huge(rng);
      if (extreme == 2 && rng() % 3 == 0) return huge(rng);
      if (extreme == 3 && rng() % 8 == 0) {
        constexpr vigil::Nanos kEdge = vigil::Nanos{1} << 56;
        const std::array<vigil::Nanos, 4> edges{kEdge, kEdge + 1, -kEdge, -kEdge - 1};
        return edges[rng() % 4];
      }
      return value(rng);
    };
    std::array<vigil::supervisor::CompactRunningStats, 3> one_by_one;
    std::array<vigil::supervisor::CompactRunningStats, 3> in_runs;
    vigil::supervisor::ScalarStats scalar_one_by_one;
    vigil::supervisor::ScalarStats scalar_in_runs;
    for (auto* s : {&one_by_one[1], &in_runs[1]}) REQUIRE(s->set_ewma_weight(0.2));
    for (int run = 0; run < 4; ++run) {
      std::array<std::vector<vigil::Nanos>, 4> v;
      for (auto& x : v) {
        x.resize(static_cast<std::size_t>(rng() % 70));  // 0 included: an empty run
        for (auto& e : x) e = draw();
      }
      for (std::size_t k = 0; k < 3; ++k) {
        for (vigil::Nanos e : v[k]) one_by_one[k].add(e);
      }
      for (vigil::Nanos e : v[3]) scalar_one_by_one.add(e);
      vigil::supervisor::CompactRunningStats::add_all<3, 1>(
          {&in_runs[0], &in_runs[1], &in_runs[2]}, {&scalar_in_runs},
          {v[0].data(), v[1].data(), v[2].data(), v[3].data()},
          {v[0].size(), v[1].size(), v[2].size(), v[3].size()});
    }
    for (std::size_t k = 0; k < 3; ++k) {
      CHECK(in_runs[k].summary() == one_by_one[k].summary());
      CHECK(in_runs[k].histogram().count() == one_by_one[k].histogram().count());
      CHECK(in_runs[k].histogram().negative_count() == one_by_one[k].histogram().negative_count());
      CHECK(in_runs[k].histogram().overflow_count() == one_by_one[k].histogram().overflow_count());
      for (std::size_t b = 0; b < vigil::supervisor::CompactRunningStats::Histogram::kBucketCount;
           ++b) {
        if (in_runs[k].histogram().count_at(b) != one_by_one[k].histogram().count_at(b)) {
          FAIL_CHECK("bucket " << b << " of statistic " << k << " differs");
        }
      }
    }
    CHECK(scalar_in_runs.summary() == scalar_one_by_one.summary());
  }
}
