#pragma once
// An independent reader of /proc/self/task/<tid>/{stat,status} for tests that check vigil's
// figures against the kernel's. Written separately from the platform layer on purpose.

#include <sched.h>
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace vigil::test {

struct ProcThread {
  std::uint64_t voluntary = 0;
  std::uint64_t involuntary = 0;
  std::uint64_t minflt = 0;
  std::uint64_t majflt = 0;
  int policy = -1;
  int rt_priority = -1;
  std::string cpus_allowed;
};

inline ProcThread read_proc_thread(int tid) {
  ProcThread p;
  const std::string dir = "/proc/self/task/" + std::to_string(tid) + "/";
  std::ifstream status(dir + "status");
  std::string key;
  std::string line;
  while (std::getline(status, line)) {
    std::istringstream ls(line);
    ls >> key;
    if (key == "voluntary_ctxt_switches:") ls >> p.voluntary;
    if (key == "nonvoluntary_ctxt_switches:") ls >> p.involuntary;
    if (key == "Cpus_allowed_list:") ls >> p.cpus_allowed;
  }
  std::ifstream statf(dir + "stat");
  std::string all((std::istreambuf_iterator<char>(statf)), std::istreambuf_iterator<char>());
  std::istringstream fs(all.substr(all.rfind(')') + 2));
  std::vector<std::string> f(3);  // fields 1 and 2 (pid, comm) are not in the stream
  std::string tok;
  while (fs >> tok) f.push_back(tok);
  if (f.size() > 41) {
    p.minflt = std::stoull(f[10]);
    p.majflt = std::stoull(f[12]);
    p.rt_priority = std::stoi(f[40]);
    p.policy = std::stoi(f[41]);
  }
  return p;
}

/// True when this process may create SCHED_FIFO threads.
inline bool have_rt_privileges() { return geteuid() == 0; }

}  // namespace vigil::test
