# benches/run's reader of one Google Benchmark JSON file (its pretty-printed format: one key per
# line): one table row per benchmark, from the median aggregate (or the run itself when there is
# one repetition), as
#
#   section|name|median|unit|floor|ratio|goal|result|order
#
#   awk -v section=TITLE -f benches/support/table.awk FILE.json
#
# Goals come from the counters goal_ratio_max, goal_ratio_min, goal_value_max, goal_value_min;
# the result is PASS or FAIL, "-" without a goal. A number is shown with the digits the table
# normally gives it (ratios 2 decimals, values 3 to 4 significant digits), and with more when
# those would put it on the other side of its goal: a ratio of 1.2041 against "<= 1.2" reads
# 1.204 FAIL, not 1.20 FAIL. No python, no jq: awk (mawk or gawk) only.
function reset() { split("", f) }
function num(x) { return x + 0 }
# v with `extra` more digits than the table's default.
function fmt(v, extra,   a) {
  if (v == "") return "-"
  v = num(v); a = v < 0 ? -v : v
  if (a >= 1e9) return sprintf("%." (4 + extra) "gG", v / 1e9)
  if (a >= 1e6) return sprintf("%." (4 + extra) "gM", v / 1e6)
  if (a >= 1e4) return sprintf("%." (3 + extra) "gk", v / 1e3)
  if (a >= 100) return sprintf("%." extra "f", v)
  if (a >= 10) return sprintf("%." (1 + extra) "f", v)
  return sprintf("%." (3 + extra) "g", v)
}
# The number a cell shows (fmt()'s suffixes read back).
function shown(s,   m) {
  m = 1
  if (s ~ /G$/) m = 1e9
  else if (s ~ /M$/) m = 1e6
  else if (s ~ /k$/) m = 1e3
  sub(/[GMk]$/, "", s)
  return num(s) * m
}
# Whether x meets a goal of kind "max" (x <= g) or "min" (x >= g).
function meets(x, kind, g) { return kind == "max" ? num(x) <= num(g) : num(x) >= num(g) }
# The cell of value v under a goal (kind "" for none): fmt(v), with more digits if it would
# read as meeting the goal when v does not, or the other way round.
function value_cell(v, kind, g,   extra, s) {
  s = fmt(v, 0)
  if (v == "" || kind == "") return s
  for (extra = 1; extra <= 8 && meets(shown(s), kind, g) != meets(v, kind, g); ++extra)
    s = fmt(v, extra)
  return s
}
# The same for a ratio: 2 decimals, more while they would read on the wrong side of the goal.
function ratio_cell(r, kind, g,   d, s) {
  if (r == "") return "-"
  s = sprintf("%.2f", num(r))
  if (kind == "") return s
  for (d = 3; d <= 10 && meets(s, kind, g) != meets(r, kind, g); ++d)
    s = sprintf("%." d "f", num(r))
  return s
}
# Registration order (random interleaving shuffles the JSON): family, then instance.
function order() { return sprintf("%04d%04d", num(f["family_index"]), num(f["per_family_instance_index"])) }
function clean(n) {
  gsub(/\/iterations:[0-9]+/, "", n); gsub(/\/manual_time/, "", n)
  gsub(/\/repeats:[0-9]+/, "", n); gsub(/\/real_time/, "", n)
  return n
}
function emit(   name, goal, pass, r, v, unit, rkind, rgoal, vkind, vgoal) {
  name = clean(f["run_name"] != "" ? f["run_name"] : f["name"])
  if (f["error_occurred"] == "true") {
    printf "%s|%s|%s|-|-|-|-|n/a|%s\n", section, name, f["error_message"], order()
    return
  }
  # The median aggregate; with one repetition there is none, and the run itself is the row.
  if (!(f["run_type"] == "aggregate" && f["aggregate_name"] == "median") &&
      !(f["run_type"] == "iteration" && num(f["repetitions"]) <= 1)) return
  unit = f["label"]
  v = f["value"]
  if (v == "") { v = f["real_time"]; unit = f["time_unit"] }
  r = f["ratio"]
  goal = "-"; pass = "-"; rkind = ""; vkind = ""
  if (f["goal_ratio_max"] != "") { rkind = "max"; rgoal = f["goal_ratio_max"]; goal = "ratio <= " fmt(rgoal, 0) }
  if (f["goal_ratio_min"] != "") { rkind = "min"; rgoal = f["goal_ratio_min"]; goal = "ratio >= " fmt(rgoal, 0) }
  if (f["goal_value_max"] != "") { vkind = "max"; vgoal = f["goal_value_max"]; goal = "<= " fmt(vgoal, 0) }
  if (f["goal_value_min"] != "") { vkind = "min"; vgoal = f["goal_value_min"]; goal = ">= " fmt(vgoal, 0) }
  # A value goal is the row's verdict when there is one; else a ratio goal.
  if (vkind != "") { pass = meets(v, vkind, vgoal) ? "PASS" : "FAIL"; rkind = "" }
  else if (rkind != "") pass = meets(r, rkind, rgoal) ? "PASS" : "FAIL"
  printf "%s|%s|%s|%s|%s|%s|%s|%s|%s\n", section, name, value_cell(v, vkind, vgoal), unit,
         fmt(f["floor"], 0), ratio_cell(r, rkind, rgoal), goal, pass, order()
}
/"benchmarks": \[/ { inb = 1; next }
!inb { next }
/^    \{/ { reset(); next }
/^    \}/ { emit(); next }
{
  line = $0; sub(/^[ \t]+/, "", line)
  if (line !~ /^"/) next
  key = line; sub(/^"/, "", key); sub(/".*$/, "", key)
  val = line; sub(/^"[^"]*":[ \t]*/, "", val); sub(/,[ \t]*$/, "", val)
  sub(/^"/, "", val); sub(/"$/, "", val)
  f[key] = val
}
