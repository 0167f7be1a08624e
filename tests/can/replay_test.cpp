#include "vigil/can/replay.hpp"

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "can_stats.hpp"  // apps/vigil: the can-stats command
#include "support/json_reader.hpp"
#include "support/shared_data.hpp"
#include "vigil/can/log/candump.hpp"

using namespace vigil::can;
using vigil::kNanosPerMilli;
using vigil::kNanosPerSecond;
using vigil::Nanos;

namespace {

// The real capture lives outside the repository: tests that read it skip when it is absent.
constexpr const char* kTruckLog = "can/j1939_truck_candump-2022-03-29.log";
std::filesystem::path truck_log() { return vigil::test::shared_data(kTruckLog); }

// Nanoseconds from milliseconds written with 3 decimals (the README's figures are in µs).
constexpr Nanos ms(double v) { return static_cast<Nanos>(v * 1e6 + (v >= 0 ? 0.5 : -0.5)); }

struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& name) : path(std::filesystem::temp_directory_path() / name) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::filesystem::path write(const std::string& file, const std::string& text) const {
    std::ofstream(path / file) << text;
    return path / file;
  }
};

struct Run {
  int code = 0;
  std::string out;
  std::string err;
};

using vigil::app::CanStatsOptions;

Run can_stats(const CanStatsOptions& o) {
  std::ostringstream out;
  std::ostringstream err;
  Run r;
  r.code = vigil::app::run_can_stats(o, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

}  // namespace

TEST_CASE("Replay of the real J1939 truck capture reproduces its independent figures",
          "[can][replay][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  LogReplay replay({.node_map = NodeMap::j1939()});
  const std::vector<std::filesystem::path> files{truck_log()};
  REQUIRE(replay.feed_files(files).has_value());
  CHECK(replay.frames() == 19535);
  CHECK(replay.first_ns() == 1648583717428998000);
  CHECK(replay.last_ns() == 1648586979907437000);
  REQUIRE(replay.files().size() == 1);
  CHECK(replay.files()[0].malformed == 0);
  CHECK(replay.bus_names() == std::vector<std::string>{"can1"});

  const CanSnapshot s = replay.snapshot();
  CHECK(s.totals.frames == 19535);
  CHECK(s.totals.dropped == 0);  // the replay never loses a record
  CHECK(s.records == 19535);
  CHECK(s.ids.size() == 23);

  const IdStats* eec1 = s.find_id(0, 0x0CF00400, true, Direction::Rx);
  REQUIRE(eec1 != nullptr);
  CHECK(eec1->frames == 2686);
  CHECK(eec1->gap_exact);
  CHECK(eec1->gap_ns.count == 2685);
  CHECK(eec1->gap_ns.p50 == ms(20.013));
  CHECK(eec1->gap_ns.min == ms(18.659));
  CHECK(eec1->gap_ns.max == ms(21.436));
  CHECK(eec1->node == 0x00);
  CHECK(eec1->function == 61444);

  const IdStats* ccvs = s.find_id(0, 0x18FEF121, true, Direction::Rx);
  REQUIRE(ccvs != nullptr);
  CHECK(ccvs->frames == 5235);
  CHECK(ccvs->gap_ns.p50 == ms(100.007));
  CHECK(ccvs->gap_ns.max == ms(2624577.524));  // beyond the histogram's range: still exact
  CHECK(ccvs->node == 0x21);

  // Three source addresses: 0x00 engine, 0x21 body controller, 0x0B brakes.
  std::set<std::uint32_t> nodes;
  std::uint64_t frames = 0;
  for (const NodeStats& n : s.nodes) {
    nodes.insert(n.node);
    frames += n.frames;
    CHECK(n.exact_count);
  }
  CHECK(nodes == std::set<std::uint32_t>{0x00, 0x0B, 0x21});
  CHECK(frames == 19535);
  CHECK(s.find_node(0, 0x00, Direction::Rx)->frames == 13695);
  CHECK(s.find_node(0, 0x21, Direction::Rx)->frames == 5689);
  CHECK(s.find_node(0, 0x0B, Direction::Rx)->frames == 151);
  CHECK(s.find_node(0, 0x21, Direction::Rx)->ids == 3);

  // Without exact percentiles the median is an upper bound within the histogram's 2^-5.
  LogReplay approx({.node_map = NodeMap::j1939(), .exact_percentiles = false});
  REQUIRE(approx.feed_files(files).has_value());
  const CanSnapshot sa = approx.snapshot();
  const IdStats* a = sa.find_id(0, 0x0CF00400, true, Direction::Rx);
  REQUIRE(a != nullptr);
  CHECK_FALSE(a->gap_exact);
  CHECK(a->gap_ns.min == ms(18.659));  // min and max stay exact
  CHECK(a->gap_ns.max == ms(21.436));
  CHECK(a->gap_ns.p50 >= ms(20.013));
  CHECK(static_cast<double>(a->gap_ns.p50) <= static_cast<double>(ms(20.013)) * (1 + 1.0 / 32));
}

namespace {
// The whitespace-separated fields of the line of `text` that starts with `start`.
std::vector<std::string> row_of(const std::string& text, const std::string& start) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(start, 0) != 0) continue;
    std::istringstream fields(line);
    std::vector<std::string> out;
    for (std::string f; fields >> f;) out.push_back(f);
    return out;
  }
  return {};
}
}  // namespace

TEST_CASE("can-stats prints the real capture's exact figures", "[can][replay][cli][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  const Run r = can_stats({.files = {truck_log()}, .node_map = NodeMapKind::J1939});
  INFO(r.out << r.err);
  CHECK(r.code == 0);
  CHECK(r.err.empty());
  CHECK(r.out.find("1 file, 19535 frames, 1648583717.428998 to 1648586979.907437") !=
        std::string::npos);
  CHECK(r.out.find("buses: 0 = can1") != std::string::npos);
  // The engine (0x00) stops after 53.7 s and the brakes (0x0B) after 15.1 s; only the body
  // controller (0x21) talks until the end of the log: at the log's end the first two are
  // "not responding" (limits learned from their traffic: 2 x p99 gap of their slowest id).
  CHECK(r.out.find("CAN status: ERROR (19535 frames, 23 ids, 3 nodes of which 1 OK, node map "
                   "j1939)") != std::string::npos);
  CHECK(r.out.find("not responding: silent for 3209s (limit 2.00s, learned: 2 x p99 gap 1.00s of "
                   "18FD7C00)") != std::string::npos);
  CHECK(r.out.find("not responding: silent for 3247s (limit 250ms, learned: 2 x p99 gap 102ms "
                   "of 18FEFA0B, at the floor)") != std::string::npos);

  // Id rows: BUS ID NODE FUNCTION(3 words) DIR FRAMES RECORDS GAP MIN/p50/MAX/MEAN (ms).
  const auto eec1 = row_of(r.out, "can1  0CF00400");
  REQUIRE(eec1.size() >= 13);
  CHECK(eec1[2] == "0x00");
  CHECK(eec1[4] == "61444");
  CHECK(eec1[7] == "2686");
  CHECK(eec1[9] == "18.659");
  CHECK(eec1[10] == "20.013");
  CHECK(eec1[11] == "21.436");
  const auto ccvs = row_of(r.out, "can1  18FEF121");
  REQUIRE(ccvs.size() >= 13);
  CHECK(ccvs[2] == "0x21");
  CHECK(ccvs[7] == "5235");
  CHECK(ccvs[10] == "100.007");
  CHECK(ccvs[11] == "2624577.524");
  CHECK(r.out.find("(gap percentiles are upper bounds") == std::string::npos);  // exact

  // Node rows: STATUS BUS NODE NAME DIR FRAMES ...
  const auto engine = row_of(r.out, "ERROR   can1  0x00");
  REQUIRE(engine.size() >= 8);
  CHECK(engine[5] == "13695");
  const auto body = row_of(r.out, "OK      can1  0x21");
  REQUIRE(body.size() >= 8);
  CHECK(body[5] == "5689");
  CHECK(row_of(r.out, "ERROR   can1  0x0B").at(5) == "151");
}

TEST_CASE("can-stats --json on the real capture", "[can][replay][cli][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  const Run r = can_stats({.files = {truck_log()}, .json = true, .node_map = NodeMapKind::J1939});
  REQUIRE(r.code == 0);
  const auto j = vigil::test::JsonParser::parse(r.out);
  CHECK(j["tool"].str() == "vigil can-stats");
  CHECK(j["frames"].number_text() == "19535");
  CHECK(j["first_timestamp_ns"].number_text() == "1648583717428998000");
  CHECK(j["node_map"].str() == "j1939");
  CHECK(j["status"].str() == "ERROR");  // engine and brakes silent at the log's end
  CHECK(j["files"][0]["frames"].number_text() == "19535");
  CHECK(j["buses"][0].str() == "can1");
  CHECK(j["ids"].array().size() == 23);
  CHECK(j["nodes"].array().size() == 3);
  bool found = false;
  for (const auto& id : j["ids"].array()) {
    if (id["id"].str() != "0CF00400") continue;
    found = true;
    CHECK(id["frames"].number_text() == "2686");
    CHECK(id["gap_exact"].boolean());
    CHECK(id["gap_ns"]["p50"].number_text() == "20013000");
    CHECK(id["gap_ns"]["min"].number_text() == "18659000");
    CHECK(id["gap_ns"]["max"].number_text() == "21436000");
    CHECK(id["node"].number_text() == "0");
    CHECK(id["function"].number_text() == "61444");
  }
  CHECK(found);
  const auto& summary = j["summary"].array();
  REQUIRE(summary.size() == 1);
  CHECK(summary[0]["frames"].number_text() == "19535");
  // The longest gap of any node: 0x21's silence (its 18FEFA21 alone paused longer, 2675 s,
  // but 18FEF121 went on sooner).
  CHECK(summary[0]["gap_us"]["max"].number() == Approx(2624577524.0));
}

TEST_CASE("can-stats with a configuration: groups, names, thresholds, filter",
          "[can][replay][cli][data]") {
  VIGIL_REQUIRE_SHARED_DATA(kTruckLog);
  const TempDir dir("vigil_can_stats_config");
  const auto config = dir.write("truck.yaml", R"(
node_map: j1939
filter: {not: {ids: [0x18FEFA21]}}
defaults:
  not_responding: {after: 1s}
nodes:
  engine: {node: 0x00, bus: 0}
  brakes: {node: 0x0B}
  retarder: {node: 0x0F}
groups:
  body: {nodes: [0x21, 0x0B], thresholds: {rx_gap: {warn: 1s, error: 3000s}}}
)");
  const Run r = can_stats({.files = {truck_log()}, .config = config});
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("CAN status: ERROR") != std::string::npos);
  CHECK(r.out.find("retarder") != std::string::npos);
  CHECK(r.out.find("not initialized: never seen") != std::string::npos);
  CHECK(r.out.find("WARN    can1  0x21") != std::string::npos);
  CHECK(r.out.find("rx gap max 2625s above 1s") != std::string::npos);  // 0x21's long silence
  CHECK(r.out.find("group body") != std::string::npos);
  CHECK(r.out.find("18FEFA21") == std::string::npos);  // filtered out
  CHECK(r.out.find("engine") != std::string::npos);

  // --node-map overrides the file's.
  const Run identity = can_stats(
      {.files = {truck_log()}, .config = config, .node_map = NodeMapKind::Identity, .ids = false});
  CHECK(identity.out.find("node map identity") != std::string::npos);
  CHECK(identity.out.find("\nIds\n") == std::string::npos);
}

TEST_CASE("can-stats errors: no file, missing file, bad configuration, malformed lines",
          "[can][replay][cli]") {
  CHECK(can_stats({}).code == 2);
  const Run missing = can_stats({.files = {"/nonexistent/x.log"}});
  CHECK(missing.code == 1);
  CHECK(missing.err.find("/nonexistent/x.log") != std::string::npos);

  const TempDir dir("vigil_can_stats_errors");
  const auto bad = dir.write("bad.yaml", "node_map: jj1939\n");
  const Run config = can_stats({.files = {truck_log()}, .config = bad});
  CHECK(config.code == 1);
  CHECK(config.err.find("bad.yaml:1:11: node_map:") != std::string::npos);

  const auto log = dir.write("m.log",
                             "(1.000000) can0 123#11\n"
                             "(1.001000) can0 123#1\n"
                             "(1.002000) can0 123#33\n");
  const Run malformed = can_stats({.files = {log}});
  CHECK(malformed.code == 0);
  CHECK(malformed.err.find("1 malformed line skipped") != std::string::npos);
  CHECK(malformed.err.find("m.log:2:") != std::string::npos);
  CHECK(malformed.out.find("2 frames") != std::string::npos);
}

TEST_CASE("can-stats merges several logs in timestamp order, candump and TRC",
          "[can][replay][cli]") {
  const TempDir dir("vigil_can_stats_merge");
  // Two candump logs of the same interface, interleaved in time, one with directions.
  const auto a = dir.write("a.log",
                           "(100.000000) can0 181#01\n"
                           "(100.020000) can0 181#01\n"
                           "(100.040000) can0 181#01\n");
  const auto b = dir.write("b.log",
                           "(100.010000) can0 181#01 R\n"
                           "(100.030000) can0 201#02 T\n"
                           "(100.050000) vcan1 181#01 R\n");
  LogReplay replay({.node_map = NodeMap::canopen()});
  const std::vector<std::filesystem::path> files{a, b};
  REQUIRE(replay.feed_files(files).has_value());
  CHECK(replay.frames() == 6);
  CHECK(replay.bus_names() == std::vector<std::string>{"can0", "vcan1"});
  const CanSnapshot s = replay.snapshot();
  const IdStats* tpdo = s.find_id(0, 0x181, false, Direction::Rx);
  REQUIRE(tpdo != nullptr);
  CHECK(tpdo->frames == 4);
  CHECK(tpdo->gap_ns.min == 10 * kNanosPerMilli);  // merged: 0, 10, 20, 40 ms
  CHECK(tpdo->gap_ns.max == 20 * kNanosPerMilli);
  CHECK(tpdo->gap_ns.count == 3);
  CHECK(s.find_id(0, 0x201, false, Direction::Tx)->frames == 1);
  CHECK(s.find_id(1, 0x181, false, Direction::Rx)->frames == 1);

  // A PEAK trace (v2.1) with two buses.
  const auto trc = dir.write("t.trc",
                             ";$FILEVERSION=2.1\n"
                             ";$COLUMNS=N,O,T,B,I,d,R,L,D\n"
                             "      1     1000.000 DT 1  0181 Rx -  1    01\n"
                             "      2     1010.000 DT 1  0181 Rx -  1    01\n"
                             "      3     1015.000 DT 2  0182 Tx -  1    02\n");
  const Run r = can_stats({.files = {trc}, .json = true, .node_map = NodeMapKind::CanOpen});
  INFO(r.out << r.err);
  REQUIRE(r.code == 0);
  const auto j = vigil::test::JsonParser::parse(r.out);
  CHECK(j["files"][0]["format"].str() == "trc");
  CHECK(j["frames"].number() == 3);
  CHECK(j["buses"].array().size() == 2);
  CHECK(j["buses"][0].str() == "bus1");
  CHECK(j["ids"][0]["gap_ns"]["max"].number() == 10'000'000);
  CHECK(j["ids"][1]["direction"].str() == "Tx");
  CHECK(j["ids"][1]["bus_name"].str() == "bus2");

  CHECK(detect_log_format("x.TRC") == LogFormat::Trc);
  CHECK(detect_log_format("x.log") == LogFormat::Candump);
  CHECK(detect_log_format("x.trc", LogFormat::Candump) == LogFormat::Candump);
}
