#pragma once
/// @file
/// The two ends of a shared-memory port, generic over the message variant:
/// `ShmProducer<Variant>` (the component's real-time side) and `ShmReader<Variant>` (the daemon).
///
/// Design. The ring is vigil's own, not boost::lockfree::spsc_queue: the reader is another
/// program that must survive a corrupted or hostile segment, and boost's ring keeps wrapped
/// indices in an implementation-defined layout that its pop() trusts (an index beyond the
/// capacity makes it read outside the buffer), while its layout may change with the Boost
/// version each side was built with. Here the layout is fixed and versioned (shm_layout.hpp),
/// the indices are 64-bit counts that never wrap, a slot is index mod capacity (a power of
/// two), and the reader validates the distance between the indices before copying anything.
///
/// Producer (one thread, the component's): keeps its write index and a cached read index
/// locally; reads the shared read index only when the cache says "full" (so the reader's line is
/// not pulled into the producer's cache every push); writes the record, then publishes the write
/// index with release. Wait-free, no allocation, no system call, no futex: a bounded number of
/// loads, stores and one memcpy. Types in the sticky mask (rare ones: identity, state changes)
/// are also copied into their mailbox under a seqlock on every push, and any message that is
/// dropped because the ring is full is copied into its type's mailbox, so a reader that attaches
/// late (a daemon started or restarted after the process) still learns the latest identity and
/// exact cumulative counters.

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "vigil/bus/shm_layout.hpp"
#include "vigil/bus/shm_segment.hpp"
#include "vigil/platform/shm.hpp"

namespace vigil::bus {

namespace detail {

template <class Variant>
constexpr std::uint32_t shm_payload_size() noexcept {
  std::uint32_t largest = 0;
  for (const std::uint32_t s : VariantTypes<Variant>::sizes) largest = s > largest ? s : largest;
  return (largest + 7U) & ~7U;
}

/// Copies the active alternative of `m` to `dst`; returns its size. Always inline: it is on the
/// real-time path (ShmProducer::push), where a call and return cost a few ns per cycle.
template <class Variant, std::size_t... I>
[[gnu::always_inline]] inline std::uint32_t copy_alternative(
    std::byte* dst, const Variant& m, std::index_sequence<I...> /*unused*/) noexcept {
  std::uint32_t size = 0;
  (void)((m.index() == I
              ? (std::memcpy(dst, std::get_if<I>(&m),
                             sizeof(std::variant_alternative_t<I, Variant>)),
                 size = static_cast<std::uint32_t>(sizeof(std::variant_alternative_t<I, Variant>)),
                 true)
              : false) ||
         ...);
  return size;
}

/// A variant holding alternative I, default-constructed: what make_alternative() copies first.
template <class Variant, std::size_t I>
inline const Variant kAlternative{std::in_place_index<I>};

/// Makes alternative `type` of `out` from `src` (sizeof that type bytes). False for a bad type.
/// The variant (trivially copyable) is copied whole from a ready one holding that alternative,
/// then the payload over it: emplace() would first zero the alternative with a string
/// instruction, ~10 ns a message in the daemon.
template <class Variant, std::size_t... I>
bool make_alternative(Variant& out, std::uint32_t type, const std::byte* src,
                      std::index_sequence<I...> /*unused*/) noexcept {
  static_assert(std::is_trivially_copyable_v<Variant>);
  return ((type == I
               ? (std::memcpy(static_cast<void*>(&out), &kAlternative<Variant, I>, sizeof(Variant)),
                  std::memcpy(static_cast<void*>(std::get_if<I>(&out)), src,
                              sizeof(std::variant_alternative_t<I, Variant>)),
                  true)
               : false) ||
          ...);
}

template <class T>
std::atomic_ref<T> shm_atomic(T& field) noexcept {
  return std::atomic_ref<T>(field);
}

}  // namespace detail

/// The producer end of a shared-memory port. One thread pushes. Does not own the mapping.
template <class Variant>
class ShmProducer {
  static_assert(std::is_trivially_copyable_v<Variant>, "shm messages must be trivially copyable");
  static constexpr std::uint32_t kPayload = detail::shm_payload_size<Variant>();
  static constexpr std::size_t kRecordWords = (sizeof(ShmRecordHeader) + kPayload) / 8;
  static constexpr auto kIndices = std::make_index_sequence<std::variant_size_v<Variant>>{};

 public:
  ShmProducer() = default;
  /// Writes into the segment at `base`, initialised with geometry `g` (type count and payload
  /// of `Variant`), mirroring the types of `sticky_mask` (shm_type_mask) in their mailboxes.
  ShmProducer(void* base, const ShmGeometry& g, std::uint32_t sticky_mask) noexcept
      : header_(static_cast<ShmSegmentHeader*>(base)),
        ring_(static_cast<std::byte*>(base) + g.ring_offset),
        record_size_(g.record_size),
        capacity_(g.capacity),
        mask_(g.capacity - 1),
        sticky_(sticky_mask),
        mailboxes_(static_cast<std::byte*>(base) + g.mailbox_offset),
        mailbox_stride_(g.mailbox_stride) {}

  /// Pushes `m`; false when the ring is full (nothing is written: the caller drops it with
  /// drop() or keeps it and retries). RT-safe: wait-free, no allocation, no system call.
  /// Always inline into the component's cycle, as the in-process port's push is.
  [[nodiscard]] [[gnu::always_inline]] bool push(const Variant& m) noexcept {
    const std::uint64_t w = write_;
    if (w - read_cache_ >= capacity_) {
      // Whatever the shared index holds, the slot written below is w mod capacity: a corrupt
      // read index can only make the ring look full.
      read_cache_ = detail::shm_atomic(header_->read_index).load(std::memory_order_acquire);
      if (w - read_cache_ >= capacity_) return false;
    }
    const std::uint64_t seq = ++seq_;
    std::byte* rec = ring_ + (w & mask_) * record_size_;
    ShmRecordHeader h{seq, static_cast<std::uint32_t>(m.index()), 0};
    h.size = detail::copy_alternative(rec + sizeof(ShmRecordHeader), m, kIndices);
    std::memcpy(rec, &h, sizeof h);
    write_ = w + 1;
    detail::shm_atomic(header_->write_index).store(w + 1, std::memory_order_release);
    detail::shm_atomic(header_->offered).store(seq, std::memory_order_relaxed);
    if (((sticky_ >> m.index()) & 1U) != 0) mail(seq, m);
    return true;
  }

  /// Records that `m` was dropped (the ring was full): counts it (`dropped_total` is the
  /// port's running count) and keeps it as the latest of its type in the mailbox. RT-safe.
  void drop(const Variant& m, std::uint64_t dropped_total) noexcept {
    const std::uint64_t seq = ++seq_;
    mail(seq, m);
    // Release (free on x86; drop() is the rare path): a reader that sees this count sees every
    // `offered` stored before it, so `dropped <= offered + 1` holds for what it reads.
    detail::shm_atomic(header_->dropped).store(dropped_total, std::memory_order_release);
    detail::shm_atomic(header_->offered).store(seq, std::memory_order_release);
  }

  /// Keeps `m` as the latest of its type in its mailbox without counting a drop: for a message
  /// the caller could not push and will push again later (a reader that drains the ring in the
  /// meantime still learns it). RT-safe.
  void keep(const Variant& m) noexcept {
    const std::uint64_t seq = ++seq_;
    mail(seq, m);
    detail::shm_atomic(header_->offered).store(seq, std::memory_order_relaxed);
  }

  /// Marks the segment closed (the component left): the reader drains it and removes it.
  /// Not RT-safe in intent (called at leave), but only a store.
  void close() noexcept {
    if (header_ == nullptr) return;
    detail::shm_atomic(header_->state)
        .store(static_cast<std::uint32_t>(ShmState::Closed), std::memory_order_release);
  }

  /// Monotonic time of the last drain by a daemon; 0 when none drained it yet.
  [[nodiscard]] std::int64_t daemon_heartbeat() const noexcept {
    return header_ == nullptr
               ? 0
               : detail::shm_atomic(header_->daemon_heartbeat_ns).load(std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint32_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] ShmSegmentHeader* header() const noexcept { return header_; }

 private:
  // Seqlock writer (one writer): odd version while the words change.
  void mail(std::uint64_t seq, const Variant& m) noexcept {
    alignas(8) std::array<std::uint64_t, kRecordWords> words{};
    auto* bytes = reinterpret_cast<std::byte*>(words.data());
    ShmRecordHeader h{seq, static_cast<std::uint32_t>(m.index()), 0};
    h.size = detail::copy_alternative(bytes + sizeof(ShmRecordHeader), m, kIndices);
    std::memcpy(bytes, &h, sizeof h);
    auto* box = reinterpret_cast<std::uint64_t*>(mailboxes_ + m.index() * mailbox_stride_);
    const std::uint64_t v = detail::shm_atomic(box[0]).load(std::memory_order_relaxed);
    detail::shm_atomic(box[0]).store(v + 1, std::memory_order_relaxed);
#if defined(__SANITIZE_THREAD__)
    // ThreadSanitizer does not model fences (GCC refuses them): each word's store is a release
    // instead, which orders it after the odd version just as the fence does.
    constexpr auto word_order = std::memory_order_release;
#else
    std::atomic_thread_fence(std::memory_order_release);
    constexpr auto word_order = std::memory_order_relaxed;
#endif
    const std::size_t n = std::min<std::size_t>(kRecordWords, record_size_ / 8);
    for (std::size_t i = 0; i < n; ++i) {
      detail::shm_atomic(box[1 + i]).store(words[i], word_order);
    }
    detail::shm_atomic(box[0]).store(v + 2, std::memory_order_release);
  }

  // Everything push() reads or writes on the producer's side fits one cache line, aligned: a
  // component at 1 kHz pushes with cold caches (it slept since its last cycle), and each line
  // touched is a miss there (the earlier layout of 88 bytes spanned two lines; a cold cycle
  // cost ~70-90 ns more than the in-process port in benches/bus/shm_bench.cpp overhead_cold).
  alignas(kShmCacheLine) ShmSegmentHeader* header_ = nullptr;
  std::byte* ring_ = nullptr;
  // Producer-local: never read from the segment.
  std::uint64_t write_ = 0;
  std::uint64_t read_cache_ = 0;
  std::uint64_t seq_ = 0;
  std::uint32_t record_size_ = 0;
  std::uint32_t capacity_ = 0;
  std::uint32_t mask_ = 0;
  std::uint32_t sticky_ = 0;
  // Only for the rare sticky types, drops and keeps.
  std::byte* mailboxes_ = nullptr;
  std::uint64_t mailbox_stride_ = 0;
};

/// Whether a record's header `h` names an alternative of `Variant` with that alternative's size;
/// false with the field and the reason in `why` (when not null) otherwise.
template <class Variant>
[[nodiscard]] bool shm_record_fits(const ShmRecordHeader& h, ShmError* why) {
  constexpr std::uint32_t n = std::variant_size_v<Variant>;
  if (h.type >= n) {
    if (why != nullptr) {
      why->field = "record.type";
      why->message = "type " + std::to_string(h.type) + " is not below " + std::to_string(n);
    }
    return false;
  }
  if (h.size != detail::VariantTypes<Variant>::sizes[h.type]) {
    if (why != nullptr) {
      why->field = "record.size";
      why->message = "type " + std::to_string(h.type) + " has " +
                     std::to_string(detail::VariantTypes<Variant>::sizes[h.type]) + " bytes, not " +
                     std::to_string(h.size);
    }
    return false;
  }
  return true;
}

/// Decodes the payload of a record whose header `h` was already copied out: the type must be an
/// alternative of `Variant` and the size that type's size (shm_record_fits). The payload's bytes
/// are copied as they are, once: validate the message's fields (e.g. bools, enums used as
/// indices, strings) with the reader's check before using them. Allocates nothing and builds no
/// message, so it may run where a bus error is caught (ShmRingReader::pop_each).
template <class Variant>
[[nodiscard]] bool decode_shm_payload(const ShmRecordHeader& h, const std::byte* payload,
                                      Variant& out) noexcept {
  constexpr std::uint32_t n = std::variant_size_v<Variant>;
  if (h.type >= n || h.size != detail::VariantTypes<Variant>::sizes[h.type]) return false;
  return detail::make_alternative(out, h.type, payload, std::make_index_sequence<n>{});
}

/// Decodes one record (ShmRecordHeader + payload) of a validated segment into `out`: the type
/// must be an alternative of `Variant` and the size that type's size. The payload's bytes are
/// copied as they are: validate the message's fields (e.g. bools, enums used as indices,
/// strings) with the reader's check before using them.
template <class Variant>
[[nodiscard]] bool decode_shm_record(const std::byte* record, Variant& out,
                                     ShmError* why) noexcept {
  ShmRecordHeader h;
  std::memcpy(&h, record, sizeof h);
  if (why != nullptr && !shm_record_fits<Variant>(h, why)) return false;
  return decode_shm_payload(h, record + sizeof(ShmRecordHeader), out);
}

/// The reader end of a shared-memory port (the daemon's): owns the mapping, validated at open.
/// Every message is decoded and passed to the reader's check before it is handed out; a record
/// or index that fails marks the segment corrupt (error() is set and nothing more is read).
/// Daemon thread only; not RT-safe.
template <class Variant>
class ShmReader {
 public:
  /// Validates a decoded message's fields in place (e.g. clamps nothing, rejects bad bools or
  /// enums); returns false and says why to reject the segment.
  using Check = bool (*)(Variant& message, std::string& why);

  /// Opens segment `name` ("/vigil.x.123.0"), checks its file (owner `uid`, mode), validates its
  /// header against `e` and attaches at its read index. The error says which field is wrong.
  static expected<ShmReader, ShmError> open(const std::string& name, const ShmExpectation& e,
                                            std::uint32_t uid, bool allow_group) {
    auto mem = platform::SharedMemory::open(name, kShmMaxSegmentSize);
    if (!mem) return unexpected<ShmError>(ShmError{"file", mem.error().message});
    if (auto f = check_shm_file(mem->info(), uid, allow_group); !f)
      return unexpected<ShmError>(f.error());
    ShmSegmentHeader copy;
    struct Ctx {
      void* src;
      ShmSegmentHeader* dst;
    } ctx{mem->data(), &copy};
    if (mem->size() < sizeof(ShmSegmentHeader)) {
      return unexpected<ShmError>(ShmError{
          "file", std::to_string(mem->size()) + " bytes, shorter than the header (truncated)"});
    }
    if (!platform::run_guarded(
            [](void* p) noexcept {
              auto& c = *static_cast<Ctx*>(p);
              // The writer stores `state` last, with release: read it first, with acquire, so
              // that a header seen Open is seen whole (a young one is retried, not rejected).
              auto* h = static_cast<ShmSegmentHeader*>(c.src);
              const std::uint32_t state =
                  detail::shm_atomic(h->state).load(std::memory_order_acquire);
              std::memcpy(c.dst, c.src, sizeof(ShmSegmentHeader));
              c.dst->state = state;
            },
            &ctx)) {
      return unexpected<ShmError>(
          ShmError{"file", "truncated while being read (bus error caught)"});
    }
    auto info = validate_shm_header(copy, mem->size(), e);
    if (!info) return unexpected<ShmError>(info.error());
    ShmReader r;
    r.mem_ = std::make_unique<platform::SharedMemory>(std::move(*mem));
    r.info_ = std::move(*info);
    r.reference_ = std::make_unique<ShmSegmentHeader>(copy);
    r.ring_ = ShmRingReader(r.mem_->data(), r.info_.geometry);
    if (auto a = r.ring_.attach(); !a) return unexpected<ShmError>(a.error());
    r.seen_ = Seen{copy.state,   copy.exit_kind,           copy.exit_code,  copy.offered,
                   copy.dropped, copy.daemon_heartbeat_ns, copy.daemon_pid, copy.drains};
    return r;
  }

  [[nodiscard]] const ShmSegmentInfo& info() const noexcept { return info_; }
  [[nodiscard]] const platform::SharedMemory& memory() const noexcept { return *mem_; }
  /// The state fields now, validated (ShmRingReader::live) and compared with what this reader
  /// saw before: the state only goes from Open to Closed, the exit record is written once (or an
  /// exit, then a signal), `offered` and `dropped` never decrease, and the daemon's own fields
  /// (heartbeat, pid, drains) hold what it wrote last. A failure marks the segment corrupt
  /// (error()).
  [[nodiscard]] expected<ShmLiveState, ShmError> live() {
    if (error_) return unexpected<ShmError>(*error_);
    auto l = ring_.live();
    if (!l) return fail(l.error());
    if (auto e = compare(*l)) return fail(std::move(*e));
    seen_.state = static_cast<std::uint32_t>(l->state);
    seen_.exit_kind = static_cast<std::uint32_t>(l->exit_kind);
    seen_.exit_code = l->exit_code;
    seen_.offered = l->offered;
    seen_.dropped = l->dropped;
    return l;
  }
  /// The state fields now, as the segment holds them (ShmRingReader::live), for a look that
  /// must not mark anything; use live() to drain.
  [[nodiscard]] expected<ShmLiveState, ShmError> peek() const noexcept { return ring_.live(); }

  /// Re-verifies what the writer set once (ShmRingReader::verify_header against the header
  /// validated at open), and an exit code without an exit record seen twice: `exit_code` is
  /// stored just before `exit_kind`, so a code without a kind lasts nanoseconds, unless it was
  /// written over. Call at a low fixed rate (its two observations should be well apart). A
  /// failure marks the segment corrupt.
  expected<void, ShmError> verify() {
    if (error_) return unexpected<ShmError>(*error_);
    ShmSegmentHeader now;
    if (auto v = ring_.verify_header(*reference_, &now); !v) return fail(v.error());
    const bool orphan_code = now.exit_kind == 0 && now.exit_code != 0;
    if (orphan_code && orphan_code_) {
      return fail(ShmError{"exit_code", std::to_string(now.exit_code) +
                                            " without an exit record (exit_kind 0), "
                                            "twice in a row: written over"});
    }
    orphan_code_ = orphan_code;
    return {};
  }

  /// Marks this daemon's drain in the segment.
  void heartbeat(std::int64_t now, std::int32_t pid) noexcept {
    ring_.heartbeat(now, pid);
    seen_.heartbeat = now;
    seen_.daemon_pid = pid;
    ++seen_.drains;
    seen_.beaten = true;
  }
  /// The header as validated at open (the writer's constant part, the state fields then).
  [[nodiscard]] const ShmSegmentHeader& header_at_open() const noexcept { return *reference_; }
  /// Marks the segment corrupt for `e` (found by the caller): nothing more is read from it.
  void set_corrupt(ShmError e) { error_ = std::move(e); }
  /// Prefetch hint for a drain to come (ShmRingReader::prefetch_records).
  void prefetch_records(std::size_t lines) const noexcept { ring_.prefetch_records(lines); }
  /// Hints the CPU to bring in this reader's own state (what a pop reads first).
  void prefetch_self() const noexcept {
    __builtin_prefetch(&ring_);
    __builtin_prefetch(&last_seq_);
  }

  /// Pops up to `max` messages into `out` (and their sequence numbers into `seqs` if not null).
  /// Sequence numbers must increase; the message must pass `check`. A bad record or message
  /// marks the segment corrupt (error()): the good ones before it are still returned, and the
  /// next call returns the error. Each record is copied once,
  /// from the ring straight into `out` (the check then reads that private copy, which the
  /// producer can no longer change).
  expected<std::size_t, ShmError> pop(Variant* out, std::uint64_t* seqs, std::size_t max,
                                      Check check) {
    if (error_) return unexpected<ShmError>(*error_);
    Decoding d{out, seqs, last_seq_};
    auto n = ring_.pop_each(max, &decode_one, &d);
    if (!n) return fail(n.error());
    // The good messages before a bad one are handed out (the counters up to the last good
    // record are kept); the bad one marks the segment corrupt, and the next call fails.
    std::size_t good = *n;
    std::optional<ShmError> bad;
    if (check != nullptr) {
      std::string reason;  // one per call, not per message
      for (std::size_t i = 0; i < *n; ++i) {
        if (!check(out[i], reason)) {
          good = i;
          bad = ShmError{"record", reason};
          break;
        }
      }
    }
    last_seq_ = good == *n || seqs == nullptr || good == 0 ? d.last_seq : seqs[good - 1];
    if (!bad && d.stopped) {
      // The record that stopped the batch stays in the ring; the segment is corrupt.
      if (d.bad.seq <= d.last_seq) {
        bad = ShmError{"record.seq", "sequence " + std::to_string(d.bad.seq) + " does not follow " +
                                         std::to_string(d.last_seq)};
      } else {
        bad.emplace();
        (void)shm_record_fits<Variant>(d.bad, &*bad);
      }
    }
    if (bad) {
      error_ = *bad;
      if (good == 0) return unexpected<ShmError>(std::move(*bad));
    }
    return good;
  }

  /// The mailboxes whose sequence number lies in (after, before), decoded, checked, in
  /// sequence order, appended to `out`. Used when attaching (what the ring no longer holds)
  /// and when the segment ends (what was dropped after the last record).
  expected<std::size_t, ShmError> mailboxes(std::vector<Variant>& out, std::uint64_t after,
                                            std::uint64_t before, Check check) {
    if (error_) return unexpected<ShmError>(*error_);
    std::vector<std::pair<std::uint64_t, Variant>> found;
    if (auto c = collect(found, after, before, check); !c) return unexpected<ShmError>(c.error());
    return commit(found, out);
  }

  /// After a drain that emptied the ring: the mailboxes newer than everything handed out so
  /// far (messages dropped, or kept for a retry, since), provided no record was published
  /// meanwhile (otherwise nothing, and the next call tries again). This keeps counters exact
  /// when the newest messages could only be dropped, e.g. while no daemon drained the ring.
  expected<std::size_t, ShmError> settle(std::vector<Variant>& out, Check check) {
    if (error_) return unexpected<ShmError>(*error_);
    auto before = live();
    if (!before) return fail(before.error());
    if (before->write_index != read_index() || before->offered <= last_seq_) return std::size_t{0};
    std::vector<std::pair<std::uint64_t, Variant>> found;
    if (auto c = collect(found, last_seq_, ~std::uint64_t{0}, check); !c) {
      return unexpected<ShmError>(c.error());
    }
    auto after = live();
    if (!after) return fail(after.error());
    if (after->write_index != before->write_index) return std::size_t{0};
    return commit(found, out);
  }

  /// The highest sequence number handed out so far (0: none).
  [[nodiscard]] std::uint64_t last_seq() const noexcept { return last_seq_; }
  /// Records consumed from the ring by this reader.
  [[nodiscard]] std::uint64_t read_index() const noexcept { return ring_.read_index(); }
  /// Set once the segment was found corrupt; nothing more is read from it.
  [[nodiscard]] const std::optional<ShmError>& error() const noexcept { return error_; }

 private:
  ShmReader() = default;

  // pop()'s state, filled by decode_one() where a bus error is caught: nothing in it allocates.
  struct Decoding {
    Variant* out;
    std::uint64_t* seqs;
    std::uint64_t last_seq;
    std::size_t done = 0;
    bool stopped = false;   // a record out of sequence or of a wrong type or size
    ShmRecordHeader bad{};  // its header
  };
  static bool decode_one(void* ctx, const std::byte* rec) noexcept {
    auto& d = *static_cast<Decoding*>(ctx);
    ShmRecordHeader h;
    std::memcpy(&h, rec, sizeof h);  // read once: the checks and the copy use this header
    if (h.seq <= d.last_seq || !decode_shm_payload(h, rec + sizeof h, d.out[d.done])) {
      d.stopped = true;
      d.bad = h;
      return false;
    }
    if (d.seqs != nullptr) d.seqs[d.done] = h.seq;
    d.last_seq = h.seq;
    ++d.done;
    return true;
  }

  expected<void, ShmError> collect(std::vector<std::pair<std::uint64_t, Variant>>& found,
                                   std::uint64_t after, std::uint64_t before, Check check) {
    std::vector<std::byte> rec(info_.geometry.record_size);
    for (std::uint32_t t = 0; t < info_.geometry.type_count; ++t) {
      if (!ring_.read_mailbox(t, rec.data())) continue;
      ShmRecordHeader h;
      std::memcpy(&h, rec.data(), sizeof h);
      if (h.seq <= after || h.seq >= before) continue;
      if (h.type != t) {
        return fail(ShmError{
            "mailbox", "mailbox " + std::to_string(t) + " holds type " + std::to_string(h.type)});
      }
      Variant v;
      ShmError why;
      if (!decode_shm_record(rec.data(), v, &why)) {
        why.field = "mailbox." + why.field;
        return fail(why);
      }
      std::string reason;
      if (check != nullptr && !check(v, reason)) return fail(ShmError{"mailbox", reason});
      found.emplace_back(h.seq, v);
    }
    return {};
  }

  std::size_t commit(std::vector<std::pair<std::uint64_t, Variant>>& found,
                     std::vector<Variant>& out) {
    std::sort(found.begin(), found.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [seq, v] : found) {
      out.push_back(v);
      last_seq_ = std::max(last_seq_, seq);
    }
    return found.size();
  }

  unexpected<ShmError> fail(ShmError e) {
    error_ = e;
    return unexpected<ShmError>(std::move(e));
  }
  // What this reader saw of the fields that change, to compare the next look with.
  struct Seen {
    std::uint32_t state = 0;
    std::uint32_t exit_kind = 0;
    std::int32_t exit_code = 0;
    std::uint64_t offered = 0;
    std::uint64_t dropped = 0;
    std::int64_t heartbeat = 0;
    std::int32_t daemon_pid = 0;
    std::uint64_t drains = 0;
    bool beaten = false;  // this reader wrote the daemon's fields at least once
  };

  [[nodiscard]] std::optional<ShmError> compare(const ShmLiveState& l) const {
    const auto state = static_cast<std::uint32_t>(l.state);
    const auto kind = static_cast<std::uint32_t>(l.exit_kind);
    if (state < seen_.state) {
      return ShmError{"state", std::to_string(state) + " after " + std::to_string(seen_.state) +
                                   " (a segment goes from Open to Closed only)"};
    }
    // The exit record is written once, or (a crash in an exit handler) an exit then a signal:
    // its kind only grows, and its code changes only with its kind.
    if (seen_.exit_kind != 0 &&
        (kind < seen_.exit_kind || (kind == seen_.exit_kind && l.exit_code != seen_.exit_code))) {
      return ShmError{kind != seen_.exit_kind ? "exit_kind" : "exit_code",
                      "exit record " + std::to_string(kind) + "/" + std::to_string(l.exit_code) +
                          " after " + std::to_string(seen_.exit_kind) + "/" +
                          std::to_string(seen_.exit_code) +
                          " (an exit record is never taken back)"};
    }
    if (l.offered < seen_.offered) {
      return ShmError{"offered", std::to_string(l.offered) + " after " +
                                     std::to_string(seen_.offered) + " (never decreases)"};
    }
    if (l.offered + 1 < last_seq_) {
      return ShmError{"offered", std::to_string(l.offered) + ", but message " +
                                     std::to_string(last_seq_) + " was received"};
    }
    if (l.dropped < seen_.dropped) {
      return ShmError{"dropped", std::to_string(l.dropped) + " after " +
                                     std::to_string(seen_.dropped) + " (never decreases)"};
    }
    if (seen_.beaten) {
      if (l.daemon_pid != seen_.daemon_pid) {
        return ShmError{"daemon_pid", std::to_string(l.daemon_pid) + ", this daemon is " +
                                          std::to_string(seen_.daemon_pid) +
                                          " (written over, or a second daemon drains the same "
                                          "segments: run one per supervisor name)"};
      }
      if (l.daemon_heartbeat_ns != seen_.heartbeat) {
        return ShmError{"daemon_heartbeat_ns", std::to_string(l.daemon_heartbeat_ns) +
                                                   ", this daemon wrote " +
                                                   std::to_string(seen_.heartbeat)};
      }
    }
    if (l.drains != seen_.drains) {
      return ShmError{"drains", std::to_string(l.drains) + ", this daemon counted " +
                                    std::to_string(seen_.drains)};
    }
    return std::nullopt;
  }

  std::unique_ptr<platform::SharedMemory> mem_;
  ShmSegmentInfo info_;
  ShmRingReader ring_;
  std::uint64_t last_seq_ = 0;
  std::optional<ShmError> error_;
  std::unique_ptr<ShmSegmentHeader> reference_;  // the header validated at open
  Seen seen_;
  bool orphan_code_ = false;  // verify() saw an exit code without an exit record
};

}  // namespace vigil::bus
