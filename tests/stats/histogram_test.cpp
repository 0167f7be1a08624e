#include "vigil/supervisor/histogram.hpp"

#include "vigil/supervisor/compact_histogram.hpp"

#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

using vigil::supervisor::CompactHistogram;
using vigil::supervisor::HistogramRange;
using vigil::supervisor::LogLinearHistogram;

namespace Catch {
template <>
struct StringMaker<HistogramRange> {
  static std::string convert(const HistogramRange& r) {
    return "[" + std::to_string(r.lowest) + ", " + std::to_string(r.highest) + "]";
  }
};
}  // namespace Catch

namespace {

using Default = LogLinearHistogram<>;

// The layout the header documents, checked at compile time.
static_assert(Default::kBucketCount == 1152);
static_assert(sizeof(Default) == 9240);
static_assert(std::is_trivially_copyable_v<Default>);
static_assert(Default::kExactLimit == 64);
static_assert(Default::kMaxTrackable == (std::int64_t{1} << 40) - 1);
static_assert(Default::kMaxRelativeError == 1.0 / 32);
static_assert(Default::bucket_index(0) == 0 && Default::bucket_index(63) == 63);
static_assert(Default::bucket_index(64) == 64 && Default::bucket_index(65) == 64);
static_assert(Default::bucket_lowest(64) == 64 && Default::bucket_highest(64) == 65);
static_assert(Default::bucket_index(Default::kMaxTrackable) == Default::kBucketCount - 1);
static_assert(Default::bucket_highest(Default::kBucketCount - 1) == Default::kMaxTrackable);
static_assert(sizeof(LogLinearHistogram<3, 20>) == (20 - 3 + 1) * 8 * 8 + 24);

// The reference: nearest rank on the sorted samples, with negative values clamped to 0 as the
// histogram does. Same expression as the implementation: rank = ceil(q * n) within [1, n].
std::int64_t exact_quantile(const std::vector<std::int64_t>& sorted, double q) {
  const auto n = sorted.size();
  auto rank = static_cast<std::size_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(n)));
  rank = std::clamp<std::size_t>(rank, 1, n);
  return std::max<std::int64_t>(sorted[rank - 1], 0);
}

// Data sets in nanoseconds; every value is below 2^40.
std::vector<std::int64_t> make_data(const std::string& kind, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::int64_t> v;
  v.reserve(n);
  if (kind == "uniform") {
    std::uniform_int_distribution<std::int64_t> d(0, 2'000'000'000);
    for (std::size_t i = 0; i < n; ++i) v.push_back(d(rng));
  } else if (kind == "exponential") {
    std::exponential_distribution<double> d(1.0 / 50'000.0);  // mean 50 us
    for (std::size_t i = 0; i < n; ++i) v.push_back(static_cast<std::int64_t>(d(rng)));
  } else if (kind == "bimodal") {
    // A 1 ms cycle with jitter, and a spike of 3 samples at ~40 ms.
    std::normal_distribution<double> d(1'000'000.0, 20'000.0);
    for (std::size_t i = 0; i + 3 < n; ++i) v.push_back(static_cast<std::int64_t>(d(rng)));
    for (std::int64_t s : {40'000'000, 40'500'001, 41'000'003}) v.push_back(s);
    std::shuffle(v.begin(), v.end(), rng);
  } else if (kind == "wide") {
    // Log-uniform over the whole tracked range: every octave gets samples.
    std::uniform_real_distribution<double> d(0.0, 40.0);
    for (std::size_t i = 0; i < n; ++i) {
      v.push_back(std::min<std::int64_t>(static_cast<std::int64_t>(std::exp2(d(rng))),
                                         (std::int64_t{1} << 40) - 1));
    }
  } else {  // constant
    v.assign(n, 123'457);
  }
  return v;
}

const std::vector<double> kQuantiles = {0.0, 1e-6, 0.001, 0.01,  0.1,   0.25,   0.5,      0.75,
                                        0.9, 0.95, 0.99,  0.995, 0.999, 0.9999, 1 - 1e-9, 1.0};

// The documented bound: exact <= reported <= exact + (exact >> S), exact below kExactLimit,
// and the range returned by quantile() holds the exact value.
template <class H>
void check_quantiles(const H& h, std::vector<std::int64_t> data) {
  std::sort(data.begin(), data.end());
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> any_q(0.0, 1.0);
  std::vector<double> qs = kQuantiles;
  for (int i = 0; i < 200; ++i) qs.push_back(any_q(rng));
  for (double q : qs) {
    const std::int64_t exact = exact_quantile(data, q);
    const std::int64_t got = h.value_at_quantile(q);
    const HistogramRange range = h.quantile(q);
    INFO("q = " << q << ", exact = " << exact << ", reported = " << got);
    CHECK(range.lowest <= exact);
    CHECK(exact <= range.highest);
    CHECK(got == range.highest);
    CHECK(got >= exact);
    CHECK(got - exact <= (exact >> H::kSubBucketBits));
    CHECK(static_cast<double>(got - exact) <= H::kMaxRelativeError * static_cast<double>(exact));
    if (exact < H::kExactLimit) CHECK(got == exact);
  }
}

template <class H>
void check_layout() {
  std::int64_t next = 0;
  for (std::size_t i = 0; i < H::kBucketCount; ++i) {
    const std::int64_t lo = H::bucket_lowest(i);
    const std::int64_t hi = H::bucket_highest(i);
    INFO("bucket " << i << " [" << lo << ", " << hi << "]");
    REQUIRE(lo == next);  // buckets tile [0, kMaxTrackable] without gap or overlap
    REQUIRE(hi >= lo);
    REQUIRE(H::bucket_index(lo) == i);
    REQUIRE(H::bucket_index(hi) == i);
    if (lo < H::kExactLimit) {
      REQUIRE(hi == lo);
    } else {
      REQUIRE(hi - lo + 1 <= (lo >> H::kSubBucketBits));  // width <= 2^-S * lowest
    }
    next = hi + 1;
  }
  CHECK(next - 1 == H::kMaxTrackable);
}

}  // namespace

TEST_CASE("LogLinearHistogram buckets tile the tracked range with width at most 2^-S of value",
          "[stats][histogram]") {
  check_layout<Default>();
  check_layout<LogLinearHistogram<1, 12>>();
  check_layout<LogLinearHistogram<3, 20>>();
  check_layout<LogLinearHistogram<7, 50>>();
}

TEST_CASE("LogLinearHistogram bucket_index agrees with the bucket bounds for random values",
          "[stats][histogram]") {
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<int> bits(1, 40);  // every bit width of a tracked value
  for (int i = 0; i < 100'000; ++i) {
    const auto v = static_cast<std::int64_t>(rng() >> (64 - bits(rng)));
    const std::size_t b = Default::bucket_index(v);
    REQUIRE(b < Default::kBucketCount);
    REQUIRE(Default::bucket_lowest(b) <= v);
    REQUIRE(v <= Default::bucket_highest(b));
  }
}

TEST_CASE("LogLinearHistogram is empty at first: count 0 and every quantile 0",
          "[stats][histogram]") {
  const auto h = std::make_unique<Default>();
  CHECK(h->count() == 0);
  CHECK(h->negative_count() == 0);
  CHECK(h->overflow_count() == 0);
  for (double q : kQuantiles) {
    CHECK(h->value_at_quantile(q) == 0);
    CHECK(h->quantile(q) == HistogramRange{0, 0});
  }
}

TEST_CASE("LogLinearHistogram with one sample reports that sample's bucket for every q",
          "[stats][histogram]") {
  for (std::int64_t s : {std::int64_t{0}, std::int64_t{1}, std::int64_t{63}, std::int64_t{64},
                         std::int64_t{1'000'003}, Default::kMaxTrackable}) {
    Default h;
    h.add(s);
    const std::size_t b = Default::bucket_index(s);
    for (double q : {0.0, 0.5, 0.999, 1.0}) {
      INFO("sample " << s << ", q " << q);
      CHECK(h.quantile(q) == HistogramRange{Default::bucket_lowest(b), Default::bucket_highest(b)});
      CHECK(h.value_at_quantile(q) >= s);
      CHECK(h.value_at_quantile(q) - s <= (s >> 5));
    }
    if (s < Default::kExactLimit) CHECK(h.value_at_quantile(0.5) == s);
  }
}

TEST_CASE("LogLinearHistogram q = 0 is the minimum, q = 1 the maximum, q is clamped",
          "[stats][histogram]") {
  Default h;
  for (std::int64_t v : {50, 7, 3000, 12, 9}) h.add(v);
  CHECK(h.value_at_quantile(0.0) == 7);
  CHECK(h.quantile(1.0) == HistogramRange{2944, 3007});  // 3000's bucket: width 2^(11-5)
  CHECK(h.value_at_quantile(-1.0) == 7);
  CHECK(h.value_at_quantile(std::nan("")) == 7);
  CHECK(h.value_at_quantile(2.0) == h.value_at_quantile(1.0));
  CHECK(h.value_at_quantile(0.2) == 7);   // rank ceil(1.0) = 1
  CHECK(h.value_at_quantile(0.21) == 9);  // rank ceil(1.05) = 2
  CHECK(h.value_at_quantile(0.6) == 12);  // rank 3
  CHECK(h.value_at_quantile(0.8) == 50);  // rank 4
}

TEST_CASE("LogLinearHistogram is exact for samples below 2^(S+1)", "[stats][histogram]") {
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<std::int64_t> d(0, Default::kExactLimit - 1);
  std::vector<std::int64_t> data;
  Default h;
  for (int i = 0; i < 10'001; ++i) {
    data.push_back(d(rng));
    h.add(data.back());
  }
  std::sort(data.begin(), data.end());
  for (double q : kQuantiles) CHECK(h.value_at_quantile(q) == exact_quantile(data, q));
  for (std::int64_t v = 0; v < Default::kExactLimit; ++v) {
    CHECK(h.count_at(static_cast<std::size_t>(v)) ==
          static_cast<std::uint64_t>(std::count(data.begin(), data.end(), v)));
  }
}

TEST_CASE("LogLinearHistogram quantiles are within 2^-S of the exact nearest-rank quantile",
          "[stats][histogram]") {
  const std::string kind =
      GENERATE(as<std::string>{}, "uniform", "exponential", "bimodal", "constant", "wide");
  const std::size_t n = GENERATE(1, 2, 3, 10, 999, 1000, 100'000);
  INFO(kind << ", n = " << n);
  const auto data = make_data(kind, n, 42 + n);
  const auto h = std::make_unique<Default>();
  for (auto v : data) h->add(v);
  REQUIRE(h->count() == data.size());
  check_quantiles(*h, data);

  // Coarser and finer layouts keep their own bound.
  const auto coarse = std::make_unique<LogLinearHistogram<2, 41>>();
  const auto fine = std::make_unique<LogLinearHistogram<8, 41>>();
  for (auto v : data) {
    coarse->add(v);
    fine->add(v);
  }
  check_quantiles(*coarse, data);
  check_quantiles(*fine, data);
}

TEST_CASE("LogLinearHistogram shows a 3-sample spike at p99.9 of 1000 but not at p99",
          "[stats][histogram]") {
  const auto data = make_data("bimodal", 1000, 3);
  Default h;
  for (auto v : data) h.add(v);
  CHECK(h.value_at_quantile(0.99) < 2'000'000);
  CHECK(h.value_at_quantile(0.997) < 2'000'000);    // rank 997: the last of the main mode
  CHECK(h.value_at_quantile(0.998) >= 40'000'000);  // rank 998: the first spike sample
  CHECK(h.value_at_quantile(0.999) >= 40'500'001);
  CHECK(h.value_at_quantile(1.0) >= 41'000'003);
  CHECK(h.value_at_quantile(1.0) <= 41'000'003 + (41'000'003 >> 5));
}

TEST_CASE("LogLinearHistogram counts negative samples as 0 and separately", "[stats][histogram]") {
  Default h;
  h.add(-1);
  h.add(std::numeric_limits<std::int64_t>::min());
  h.add(5);
  CHECK(h.count() == 3);
  CHECK(h.negative_count() == 2);
  CHECK(h.overflow_count() == 0);
  CHECK(h.count_at(0) == 2);
  CHECK(h.value_at_quantile(0.0) == 0);
  CHECK(h.value_at_quantile(0.5) == 0);
  CHECK(h.value_at_quantile(1.0) == 5);
}

TEST_CASE("LogLinearHistogram counts samples above 2^E - 1 as overflow and reports them",
          "[stats][histogram]") {
  Default h;
  h.add(Default::kMaxTrackable);  // the last tracked value
  h.add(Default::kMaxTrackable + 1);
  h.add(std::numeric_limits<std::int64_t>::max());
  h.add(10);
  CHECK(h.count() == 4);
  CHECK(h.overflow_count() == 2);
  CHECK(h.negative_count() == 0);
  CHECK(h.count_at(Default::kBucketCount - 1) == 1);
  CHECK(h.value_at_quantile(0.25) == 10);
  CHECK(h.value_at_quantile(0.5) == Default::kMaxTrackable);
  CHECK(h.quantile(0.75) == HistogramRange{Default::kMaxTrackable + 1, Default::kOverflowValue});
  CHECK(h.value_at_quantile(1.0) == Default::kOverflowValue);

  Default all_over;  // overflow holds more than half: the scan from the bottom ends there too
  for (int i = 0; i < 5; ++i) all_over.add(std::int64_t{1} << 50);
  CHECK(all_over.value_at_quantile(0.0) == Default::kOverflowValue);
  CHECK(all_over.value_at_quantile(0.5) == Default::kOverflowValue);
}

TEST_CASE("LogLinearHistogram merge equals adding every sample to one histogram",
          "[stats][histogram]") {
  auto a_data = make_data("exponential", 5000, 10);
  auto b_data = make_data("bimodal", 3000, 11);
  b_data.push_back(-4);
  b_data.push_back(std::int64_t{1} << 45);
  const auto a = std::make_unique<Default>();
  const auto b = std::make_unique<Default>();
  const auto all = std::make_unique<Default>();
  for (auto v : a_data) {
    a->add(v);
    all->add(v);
  }
  for (auto v : b_data) {
    b->add(v);
    all->add(v);
  }
  a->merge(*b);
  CHECK(a->count() == all->count());
  CHECK(a->negative_count() == 1);
  CHECK(a->overflow_count() == 1);
  for (std::size_t i = 0; i < Default::kBucketCount; ++i)
    REQUIRE(a->count_at(i) == all->count_at(i));
  for (double q : kQuantiles) CHECK(a->value_at_quantile(q) == all->value_at_quantile(q));

  const auto empty = std::make_unique<Default>();
  a->merge(*empty);
  CHECK(a->count() == all->count());
  empty->merge(*all);
  for (double q : kQuantiles) CHECK(empty->value_at_quantile(q) == all->value_at_quantile(q));
}

TEST_CASE("LogLinearHistogram reset forgets every sample", "[stats][histogram]") {
  Default h;
  for (auto v : make_data("uniform", 1000, 12)) h.add(v);
  h.add(-1);
  h.add(std::int64_t{1} << 41);
  h.reset();
  CHECK(h.count() == 0);
  CHECK(h.negative_count() == 0);
  CHECK(h.overflow_count() == 0);
  for (std::size_t i = 0; i < Default::kBucketCount; ++i) REQUIRE(h.count_at(i) == 0);
  CHECK(h.value_at_quantile(0.5) == 0);
  h.add(17);
  CHECK(h.value_at_quantile(0.5) == 17);
}

// ---- CompactHistogram: the same buckets, allocated for the seen range only ----------------------

using Compact = CompactHistogram<>;
static_assert(Compact::kBucketCount == Default::kBucketCount);
static_assert(Compact::kMaxRelativeError == Default::kMaxRelativeError);
static_assert(Compact::kChunkBuckets == 32 && Compact::kChunks == 36);

TEST_CASE("CompactHistogram quantiles are within 2^-S of exact ones and equal the fixed layout's",
          "[stats][histogram][compact]") {
  const std::string kind =
      GENERATE(as<std::string>{}, "uniform", "exponential", "bimodal", "constant", "wide");
  const std::size_t n = GENERATE(1, 2, 3, 10, 999, 1000, 100'000);
  INFO(kind << ", n = " << n);
  const auto data = make_data(kind, n, 42 + n);
  Compact c;
  const auto fixed = std::make_unique<Default>();
  for (auto v : data) {
    c.add(v);
    fixed->add(v);
  }
  REQUIRE(c.count() == data.size());
  check_quantiles(c, data);  // the documented bound against exact percentiles
  for (std::size_t i = 0; i < Default::kBucketCount; ++i)
    REQUIRE(c.count_at(i) == fixed->count_at(i));
  for (double q : kQuantiles) {
    CHECK(c.quantile(q) == fixed->quantile(q));
    CHECK(c.value_at_quantile(q) == fixed->value_at_quantile(q));
  }
  constexpr std::array<double, 4> kQs{0.5, 0.9, 0.99, 0.999};
  std::array<std::int64_t, 4> a{};
  std::array<std::int64_t, 4> b{};
  c.values_at_quantiles(kQs, a);
  fixed->values_at_quantiles(kQs, b);
  CHECK(a == b);
  CHECK(c.heap_bytes() <= sizeof(std::uint64_t) * Default::kBucketCount);
}

TEST_CASE("CompactHistogram allocates the chunks of the seen range only, growing both ways",
          "[stats][histogram][compact]") {
  Compact h;
  CHECK(h.allocated_buckets() == 0);
  CHECK(h.heap_bytes() == 0);
  CHECK(h.value_at_quantile(0.5) == 0);
  CHECK(h.count_at(100) == 0);
  // A cycle time of 50-62 us: one octave [32768, 65535], one chunk of 32 buckets (256 bytes).
  for (std::int64_t v = 50'000; v <= 62'000; v += 100) h.add(v);
  CHECK(h.allocated_buckets() == 32);
  CHECK(h.heap_bytes() == 256);
  CHECK(h.first_allocated() == Compact::bucket_index(32'768));
  // Upwards: a 1 ms outlier extends the block to [32768, 2^20): five chunks.
  h.add(1'000'000);
  CHECK(h.allocated_buckets() == 5 * 32);
  // Downwards: 3 ns is exact (chunk 0).
  h.add(3);
  CHECK(h.first_allocated() == 0);
  CHECK(h.allocated_buckets() == Compact::bucket_index(1'000'000) / 32 * 32 + 32);
  CHECK(h.count_at(3) == 1);
  CHECK(h.count_at(Compact::bucket_index(1'000'000)) == 1);
  CHECK(h.value_at_quantile(0.0) == 3);
  CHECK(h.value_at_quantile(1.0) == Compact::bucket_highest(Compact::bucket_index(1'000'000)));
  // Negative and overflowed samples need no bucket memory.
  const auto before = h.allocated_buckets();
  h.add(-5);
  h.add(std::int64_t{1} << 45);
  CHECK(h.allocated_buckets() == before);
  CHECK(h.negative_count() == 1);
  CHECK(h.overflow_count() == 1);
  CHECK(h.count_at(0) == 1);  // the negative one counts as 0
  CHECK(h.lost_count() == 0);
  // The whole range: never more than the fixed layout.
  h.add(Compact::kMaxTrackable);
  CHECK(h.allocated_buckets() == Compact::kBucketCount);
}

TEST_CASE("CompactHistogram merge, reset, copy and move keep every count",
          "[stats][histogram][compact]") {
  auto a_data = make_data("exponential", 5000, 10);
  auto b_data = make_data("bimodal", 3000, 11);
  b_data.push_back(-4);
  b_data.push_back(std::int64_t{1} << 45);
  Compact a;
  Compact b;
  const auto all = std::make_unique<Default>();
  for (auto v : a_data) {
    a.add(v);
    all->add(v);
  }
  for (auto v : b_data) {
    b.add(v);
    all->add(v);
  }
  a.merge(b);
  CHECK(a.count() == all->count());
  CHECK(a.negative_count() == 1);
  CHECK(a.overflow_count() == 1);
  for (std::size_t i = 0; i < Default::kBucketCount; ++i)
    REQUIRE(a.count_at(i) == all->count_at(i));
  for (double q : kQuantiles) CHECK(a.value_at_quantile(q) == all->value_at_quantile(q));
  Compact empty;
  empty.merge(a);
  for (double q : kQuantiles) CHECK(empty.value_at_quantile(q) == all->value_at_quantile(q));

  const Compact copy(a);  // deep
  a.add(7);
  CHECK(copy.count() == all->count());
  CHECK(copy.count_at(7) == all->count_at(7));
  Compact moved(std::move(a));
  CHECK(moved.count() == all->count() + 1);
  CHECK(a.count() == 0);              // NOLINT(bugprone-use-after-move): moved-from is empty
  CHECK(a.allocated_buckets() == 0);  // NOLINT(bugprone-use-after-move)
  const auto block = moved.allocated_buckets();
  moved.reset();
  CHECK(moved.count() == 0);
  CHECK(moved.allocated_buckets() == block);  // the block is kept for the same range
  for (std::size_t i = 0; i < Default::kBucketCount; ++i) REQUIRE(moved.count_at(i) == 0);
  moved.add(17);
  CHECK(moved.value_at_quantile(0.5) == 17);
}

namespace {
template <class TestType>
void runs_count_as_each_sample() {
  // add_all keeps each histogram's totals and block in registers over its run and interleaves
  // the runs: every count, and the compact block's growth, must equal add()'s, with negative,
  // overflowed and growing samples among them; runs within range counted with and without the
  // checks.
  std::mt19937_64 rng(2111);
  int unchecked = 0;
  const std::array<std::int64_t, 6> scale{100, 70'000, 5'000'000, 1LL << 39, 1LL << 41, 40};
  for (int round = 0; round < 40; ++round) {
    auto one_by_one = std::make_unique<std::array<TestType, 3>>();
    auto in_runs = std::make_unique<std::array<TestType, 3>>();
    for (int run = 0; run < 5; ++run) {
      std::array<std::vector<std::int64_t>, 3> v;
      const bool non_negative = rng() % 2 == 0;
      for (auto& x : v) {
        x.resize(static_cast<std::size_t>(rng() % 70));  // 0 included: an empty run
        const std::int64_t top = scale[rng() % scale.size()];
        std::uniform_int_distribution<std::int64_t> value(non_negative ? 0 : -top / 10 - 1, top);
        for (auto& e : x) e = value(rng);
      }
      for (std::size_t k = 0; k < 3; ++k) {
        for (std::int64_t e : v[k]) (*one_by_one)[k].add(e);
      }
      // Runs known to be within range may skip the checks (in_range); the others may not.
      bool in_range = true;
      for (const auto& x : v) {
        for (std::int64_t e : x) in_range = in_range && e >= 0 && e <= TestType::kMaxTrackable;
      }
      TestType::template add_all<3>(
          {&(*in_runs)[0], &(*in_runs)[1], &(*in_runs)[2]}, {v[0].data(), v[1].data(), v[2].data()},
          {v[0].size(), v[1].size(), v[2].size()}, in_range && rng() % 2 == 0 && ++unchecked > 0);
    }
    for (std::size_t k = 0; k < 3; ++k) {
      const TestType& a = (*in_runs)[k];
      const TestType& b = (*one_by_one)[k];
      REQUIRE(a.count() == b.count());
      REQUIRE(a.negative_count() == b.negative_count());
      REQUIRE(a.overflow_count() == b.overflow_count());
      if constexpr (requires { a.allocated_buckets(); }) {
        REQUIRE(a.first_allocated() == b.first_allocated());
        REQUIRE(a.allocated_buckets() == b.allocated_buckets());
        REQUIRE(a.lost_count() == b.lost_count());
      }
      for (std::size_t i = 0; i < TestType::kBucketCount; ++i)
        REQUIRE(a.count_at(i) == b.count_at(i));
    }
  }
  CHECK(unchecked > 10);  // the unchecked path was taken
}
}  // namespace

// A plain TEST_CASE, not TEMPLATE_TEST_CASE: the cobalt build registers tests from their sources.
TEST_CASE("Histograms given runs of samples, several at once, count as given each sample",
          "[stats][histogram]") {
  SECTION("LogLinearHistogram") { runs_count_as_each_sample<LogLinearHistogram<5, 40>>(); }
  SECTION("CompactHistogram") { runs_count_as_each_sample<CompactHistogram<5, 40>>(); }
}
