#include "vigil/config/reloadable.hpp"

#include <pthread.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "vigil/config/file_watcher.hpp"

using namespace vigil::config;
namespace fs = std::filesystem;

namespace {

// A fresh directory under the system's temporary directory, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::random_device random;
    path_ = fs::temp_directory_path() /
            ("vigil-config-test-" + std::to_string(random()) + std::to_string(random()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// Replaces `file` atomically (write a sibling, set its time stamp, rename) so that a concurrent
// reader sees the old or the new content, never half of it. Each call gets a time stamp one
// second later than the previous one: a change is visible whatever the file system's timer
// resolution, without sleeping.
void write_file(const fs::path& file, const std::string& text) {
  static const fs::file_time_type base = fs::file_time_type::clock::now() - std::chrono::hours(1);
  static std::atomic<int> writes{0};
  const fs::path temporary = file.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << text;
  }
  fs::last_write_time(temporary, base + std::chrono::seconds(++writes));
  fs::rename(temporary, file);
}

struct Pair {
  int a = 0;
  int b = 0;
};

// A loader returning the value itself (errors go through the document).
Pair load_pair(const Node& root) {
  root.reject_unknown_keys({"a", "b"});
  return Pair{root.required<int>("a"), root.required<int>("b")};
}

std::string pair_text(int v) {
  return "a: " + std::to_string(v) + "\nb: " + std::to_string(v) + "\n";
}

}  // namespace

TEST_CASE("Reloadable::open loads the first value or returns every error", "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());
  CHECK(pair->current()->a == 1);
  CHECK(pair->generation() == 1);
  CHECK(pair->last_errors().empty());
  CHECK(pair->path() == file);

  write_file(file, "a: x\nc: 2\n");
  auto bad = Reloadable<Pair>::open(file, load_pair);
  REQUIRE_FALSE(bad.has_value());
  const std::string f = file.string();
  CHECK(bad.error() == ConfigErrors{{f, 1, 1, "b", "required key is missing"},
                                    {f, 1, 4, "a", "expected an integer, got 'x'"},
                                    {f, 2, 1, "c", "unknown key; expected one of: a, b"}});

  auto missing = Reloadable<Pair>::open(dir.path() / "nope.yaml", load_pair);
  REQUIRE_FALSE(missing.has_value());
  CHECK(missing.error()[0].message == "cannot read file: No such file or directory");
}

TEST_CASE("A good reload publishes the new value and increments the generation",
          "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());
  const std::shared_ptr<const Pair> old = pair->current();

  write_file(file, pair_text(2));
  const auto generation = pair->reload();
  REQUIRE(generation.has_value());
  CHECK(*generation == 2);
  CHECK(pair->generation() == 2);
  CHECK(pair->current()->a == 2);
  CHECK(old->a == 1);  // a reader that still holds the old value keeps it intact
}

TEST_CASE("A bad reload keeps the previous value and reports the errors", "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());

  write_file(file, "a: 2\nb: [3]\n");
  const auto failed = pair->reload();
  REQUIRE_FALSE(failed.has_value());
  const ConfigErrors expected{{file.string(), 2, 4, "b", "expected an integer, got a sequence"}};
  CHECK(failed.error() == expected);
  CHECK(pair->last_errors() == expected);
  CHECK(pair->current()->a == 1);
  CHECK(pair->generation() == 1);

  write_file(file, "a: 2\nb: 2\na: 5\n");  // a duplicate key fails at load time
  REQUIRE_FALSE(pair->reload().has_value());
  CHECK(pair->last_errors()[0].message == "duplicate key (first defined at line 1, column 1)");

  fs::remove(file);
  REQUIRE_FALSE(pair->reload().has_value());
  CHECK(pair->last_errors()[0].message == "cannot read file: No such file or directory");
  CHECK(pair->current()->a == 1);

  write_file(file, pair_text(3));
  REQUIRE(pair->reload().has_value());
  CHECK(pair->last_errors().empty());
  CHECK(pair->current()->a == 3);
  CHECK(pair->generation() == 2);
}

TEST_CASE("A loader that throws during a reload keeps the previous value", "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, [](const Node& root) {
    Pair p = load_pair(root);
    if (p.a == 13) throw std::runtime_error("unlucky");
    return p;
  });
  REQUIRE(pair.has_value());
  write_file(file, pair_text(13));
  const auto failed = pair->reload();
  REQUIRE_FALSE(failed.has_value());
  CHECK(failed.error() == ConfigErrors{{file.string(), 0, 0, "", "the loader failed: unlucky"}});
  CHECK(pair->current()->a == 1);
}

TEST_CASE("poll reloads when the modification time or size changed, and only then",
          "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());
  CHECK(pair->poll() == ReloadStatus::Unchanged);

  write_file(file, pair_text(2));  // same size, later time stamp
  CHECK(pair->poll() == ReloadStatus::Reloaded);
  CHECK(pair->current()->a == 2);
  CHECK(pair->poll() == ReloadStatus::Unchanged);

  // Same time stamp, different size.
  const auto stamp = fs::last_write_time(file);
  { std::ofstream(file, std::ios::trunc) << pair_text(40); }
  fs::last_write_time(file, stamp);
  CHECK(pair->poll() == ReloadStatus::Reloaded);
  CHECK(pair->current()->a == 40);

  write_file(file, "a: 5\n");
  CHECK(pair->poll() == ReloadStatus::Failed);
  CHECK(pair->poll() == ReloadStatus::Unchanged);  // a bad file is reported once
  CHECK(pair->last_errors().size() == 1);
  CHECK(pair->current()->a == 40);

  fs::remove(file);
  CHECK(pair->poll() == ReloadStatus::Failed);
  CHECK(pair->poll() == ReloadStatus::Unchanged);

  write_file(file, pair_text(6));
  CHECK(pair->poll() == ReloadStatus::Reloaded);
  CHECK(pair->current()->a == 6);
  CHECK(pair->generation() == 4);
}

TEST_CASE("Subscribers are called after each successful reload until they unsubscribe",
          "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());
  std::vector<std::pair<int, std::uint64_t>> seen;
  const std::uint64_t id =
      pair->subscribe([&](const std::shared_ptr<const Pair>& value, std::uint64_t generation) {
        seen.emplace_back(value->a, generation);
      });
  write_file(file, pair_text(2));
  REQUIRE(pair->reload().has_value());
  write_file(file, "a: oops\n");
  REQUIRE_FALSE(pair->reload().has_value());
  write_file(file, pair_text(3));
  REQUIRE(pair->reload().has_value());
  pair->unsubscribe(id);
  pair->unsubscribe(id + 100);  // unknown ids are ignored
  write_file(file, pair_text(4));
  REQUIRE(pair->reload().has_value());
  CHECK(seen == std::vector<std::pair<int, std::uint64_t>>{{2, 2}, {3, 3}});
}

TEST_CASE("Readers see whole values while another thread reloads", "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(0));
  auto opened = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(opened.has_value());
  const Reloadable<Pair> pair = *opened;  // a copy is a handle on the same state

  std::atomic<bool> done{false};
  std::atomic<int> torn{0};
  std::atomic<int> backwards{0};
  std::vector<std::thread> readers;
  for (int r = 0; r < 2; ++r) {
    readers.emplace_back([&] {
      int last = 0;
      std::uint64_t last_generation = 0;
      while (!done.load()) {
        const std::uint64_t generation = pair.generation();
        const std::shared_ptr<const Pair> value = pair.current();
        if (value->a != value->b) ++torn;
        if (value->a < last || generation < last_generation) ++backwards;
        last = value->a;
        last_generation = generation;
      }
    });
  }
  constexpr int kReloads = 100;
  for (int i = 1; i <= kReloads; ++i) {
    write_file(file, pair_text(i));
    REQUIRE(opened->reload().has_value());
  }
  done = true;
  for (std::thread& t : readers) t.join();
  CHECK(torn == 0);
  CHECK(backwards == 0);
  CHECK(pair.current()->a == kReloads);
  CHECK(pair.generation() == kReloads + 1);
}

TEST_CASE("FileWatcher applies an edited file and stops promptly", "[config][reload]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());

  FileWatcher watcher(vigil::kNanosPerMilli);
  watcher.watch(*pair);
  write_file(file, pair_text(2));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (pair->generation() < 2 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(pair->current()->a == 2);

  write_file(file, "a: [bad]\nb: 3\n");
  while (pair->last_errors().empty() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(pair->last_errors().size() == 1);
  CHECK(pair->current()->a == 2);
  watcher.stop();
  watcher.stop();  // idempotent
  CHECK(watcher.rounds() > 0);

  // A watcher with a long period wakes up at once to stop.
  const auto start = std::chrono::steady_clock::now();
  {
    FileWatcher slow(3'600 * vigil::kNanosPerSecond);
    slow.watch(*pair);
  }
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(5));
}

TEST_CASE("FileWatcher's thread has the stack it was given", "[config][reload][memory]") {
  TempDir dir;
  const fs::path file = dir.path() / "pair.yaml";
  write_file(file, pair_text(1));
  auto pair = Reloadable<Pair>::open(file, load_pair);
  REQUIRE(pair.has_value());
  std::atomic<std::size_t> stack{0};
  pair->subscribe([&](const std::shared_ptr<const Pair>&, std::uint64_t) {
    pthread_attr_t attr;  // read independently of the platform layer
    std::size_t size = 0;
    if (pthread_getattr_np(pthread_self(), &attr) == 0) {
      pthread_attr_getstacksize(&attr, &size);
      pthread_attr_destroy(&attr);
    }
    stack.store(size);
  });
  FileWatcher watcher(vigil::kNanosPerMilli, 320 * 1024);
  watcher.watch(*pair);
  write_file(file, pair_text(2));  // reloaded, and the subscriber called, on the watcher's thread
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (stack.load() == 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  // glibc may hand the thread a cached stack of up to 4 x the size asked (tests/support/stack.hpp).
  CHECK(stack.load() >= 320 * 1024);
  CHECK(stack.load() <= 4 * 320 * 1024);
}
