#include "tests/bench/detection/detection_harness.hpp"

#include "common/wire_messages.hpp"
#include "host/demo/commission.hpp"
#include "host/demo/demo_plan.hpp"
#include "host/demo/in_process_link.hpp"
#include "host/link/session.hpp"
#include "host/report/html_report.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace btsm::bench {
namespace {

int state_of(const wire::Sample& s, int c) { return s.channel_status[c] & wire::kStatusStateMask; }

// Worst WARN/ALARM state over the channels (only thermal channels ever show them).
int worst_thermal(const wire::Sample& s) {
  int w = kNormal;
  for (int c = 0; c < wire::kChannels; ++c) {
    const int st = state_of(s, c);
    if ((st == kWarn || st == kAlarm) && st > w) w = st;
  }
  return w;
}

// What a child sends back through its pipe.
struct ChildReport {
  double warn_s = -1, alarm_s = -1, sensor_s = -1;
  int warn_channel = 0, alarm_channel = 0, sensor_channel = 0;
  int ok = 0;
  char error[240] = {};
};

// Continues the module's history with `fault` from now on and watches its SAMPLE frames.
ChildReport watch_fault(link::Session& session, sim::SimModule& module, sim::FaultSpec fault, double window_s,
                        bool stop_at_alarm) {
  ChildReport r;
  const double t0 = module.sim_time_s();
  fault.start_s = t0;
  module.inject_fault(fault);
  for (;;) {
    const auto ev = session.next_sample(link::Millis(60000));
    if (!ev) throw std::runtime_error("no SAMPLE from the module for 60 s");
    const wire::Sample& s = ev->sample;
    const double dt = s.time_ms / 1000.0 - t0;
    if (dt < 0) continue;  // swept before the fault began
    for (int c = 0; c < wire::kChannels; ++c) {
      const int st = state_of(s, c);
      if ((st == kWarn || st == kAlarm) && r.warn_s < 0) r.warn_s = dt, r.warn_channel = c + 1;
      if (st == kAlarm && r.alarm_s < 0) r.alarm_s = dt, r.alarm_channel = c + 1;
      if (st == kSensorFault && r.sensor_s < 0) r.sensor_s = dt, r.sensor_channel = c + 1;
    }
    if (dt >= window_s || (stop_at_alarm && r.alarm_s >= 0)) break;
  }
  r.ok = 1;
  return r;
}

// A fault run in a forked copy of this process (the whole simulated module included): the
// parent's own simulation is untouched, so every child starts from the state of the moment.
struct Child {
  pid_t pid = -1;
  int fd = -1;  // read end of the pipe that carries the ChildReport
};

template <class Fn>
Child spawn_child(Fn fn) {
  std::fflush(nullptr);
  std::cout.flush();
  std::cerr.flush();
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe() failed");
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork() failed");
  if (pid == 0) {
    ::close(fds[0]);
    ChildReport rep;
    try {
      rep = fn();
    } catch (const std::exception& e) {
      rep.ok = 0;
      std::snprintf(rep.error, sizeof rep.error, "%s", e.what());
    }
    // One write below PIPE_BUF: it completes without a reader, so the child can exit before the
    // parent gets to it.
    static_assert(sizeof(ChildReport) <= 512, "a report must fit the pipe in one atomic write");
    const ssize_t w = ::write(fds[1], &rep, sizeof rep);
    ::_exit(w == ssize_t(sizeof rep) ? 0 : 1);
  }
  ::close(fds[1]);
  return Child{pid, fds[0]};
}

// The report of a child that has exited with `status`.
ChildReport collect_child(const Child& c, int status) {
  ChildReport rep;
  size_t got = 0;
  while (got < sizeof rep) {
    const ssize_t n = ::read(c.fd, reinterpret_cast<char*>(&rep) + got, sizeof rep - got);
    if (n <= 0) break;
    got += size_t(n);
  }
  ::close(c.fd);
  if (got != sizeof rep) {
    rep = ChildReport();
    std::snprintf(rep.error, sizeof rep.error, "the fault run ended without a report (status %d)", status);
  }
  return rep;
}

// Runs run(i) for i in [0, n) in forked children, at most `jobs` at a time, and returns their
// reports in order of i. The children are independent copies of one state, so the reports do not
// depend on `jobs`; only the wall time does.
template <class Run>
std::vector<ChildReport> run_children(size_t n, int jobs, Run run) {
  std::vector<ChildReport> reports(n);
  std::vector<std::pair<size_t, Child>> running;
  size_t next = 0;
  while (next < n || !running.empty()) {
    while (next < n && running.size() < size_t(std::max(1, jobs))) {
      const size_t i = next++;
      running.emplace_back(i, spawn_child([&run, i] { return run(i); }));
    }
    int status = 0;
    const pid_t done = ::waitpid(-1, &status, 0);
    if (done < 0) throw std::runtime_error("waitpid() failed while fault runs were running");
    const auto it = std::find_if(running.begin(), running.end(),
                                 [done](const std::pair<size_t, Child>& r) { return r.second.pid == done; });
    if (it == running.end()) continue;  // not one of ours
    reports[it->first] = collect_child(it->second, status);
    running.erase(it);
  }
  return reports;
}

std::string minutes(double s, double window_s) {
  return s < 0 ? fmt::format("> {:.0f}", window_s / 60) : fmt::format("{:.1f}", s / 60);
}

const char* kChannelNames[wire::kChannels] = {"T1 rear bearing", "T2 housing", "T3 front bearing", "T4 ambient",
                                              "T5 shaft end"};

}  // namespace

DetectionResult run_detection(const DetectionOptions& o) {
  const auto wall0 = std::chrono::steady_clock::now();
  const auto say = [&o](const std::string& s) { if (o.progress) o.progress(s); };
  DetectionResult res;
  fs::create_directories(o.out_dir);

  // --- 1. Commissioning, as the demo does it -------------------------------------------------------
  const demo::DemoPlan plan = demo::make_demo_plan(o.quick_identification);
  const demo::ModuleKey key = demo::make_module_key(o.out_dir);
  sim::SimModuleOptions so = demo::demo_module_options(plan, o.effect, key);
  so.board = o.board;
  so.elf_path = o.elf_path;
  so.log = say;
  sim::SimModule module(so);
  demo::InProcessLink link(module);
  link::Session session(link);
  res.board = module.board_kind();
  report::HtmlReport page("BTSM detection benchmark: commissioning of the module");
  std::string step = "identify the module";
  demo::Commissioned com;
  try {
    demo::CommissionIo io;
    io.out_dir = o.out_dir;
    io.board_kind = res.board;
    io.page = &page;
    io.step = &step;
    io.say = say;
    com = demo::commission_module(session, plan, key, io);
  } catch (const std::exception& e) {
    throw std::runtime_error("commissioning failed at '" + step + "': " + e.what());
  }
  page.write((fs::path(o.out_dir) / "index.html").string());
  for (int j = 0; j < wire::kChannels; ++j) {
    res.drift_K[j] = com.analysis.drift_K[j];
    res.alarm_evidence_K_min[j] = com.analysis.alarm_evidence_K_min[j];
  }

  // --- 2. Production, fault-free, with the faults forked off at the chosen moments ------------------
  const ProductionProfile profile = make_production_profile(o.profile);
  res.profile = profile.describe();
  const std::vector<ProfileMoment> moments = pick_moments(profile, o.kinds, o.moments_per_kind);
  std::vector<sim::SpeedSegment> segs{{o.soak_h * 3600, 0}};
  segs.insert(segs.end(), profile.segments.begin(), profile.segments.end());
  segs.push_back({1e7, 0});
  module.replace_speed_from_now(segs);
  const double t_prod = module.sim_time_s() + o.soak_h * 3600;
  const double end_s = t_prod + profile.duration_s();
  say(fmt::format("production profile: {}; {} fault moments", res.profile, moments.size()));

  FaultFreeRun& ff = res.fault_free;
  ff.hours = profile.duration_s() / 3600;
  // The fault-free run sample by sample (every 6th: 30 s), so a false WARN can be traced to what
  // the plant did and what the model predicted.
  std::ofstream trace(fs::path(o.out_dir) / "fault_free.csv");
  trace << "t_h,rpm";
  for (int c = 1; c <= wire::kChannels; ++c) trace << fmt::format(",T{0}_c,P{0}_c,S{0}", c);
  trace << "\n";
  long trace_n = 0;
  int prev[wire::kChannels] = {};
  bool acked = false;
  size_t next_moment = 0;
  double next_progress_h = 6;
  wire::Sample last{};
  for (;;) {
    const auto ev = session.next_sample(link::Millis(60000));
    if (!ev) throw std::runtime_error("no SAMPLE from the module for 60 s in the fault-free run");
    const wire::Sample& s = ev->sample;
    const double t = s.time_ms / 1000.0;
    if (t >= end_s) break;
    if (t >= t_prod) {
      // The fault runs of the moments that have come.
      while (next_moment < moments.size() && t - t_prod >= moments[next_moment].t_s) {
        const ProfileMoment& m = moments[next_moment++];
        struct FaultJob {
          std::string name, place;
          sim::FaultSpec spec;
          double window_s;
          bool stop_at_alarm;
        };
        std::vector<FaultJob> jobs;
        for (double w : o.heats_w)
          for (sim::BearingPlace place : o.places) {
            sim::FaultSpec f;
            f.kind = sim::FaultKind::BearingHeat;
            f.heat_w = w;
            f.place = place;
            jobs.push_back({fmt::format("bearing {:.0f} W", w), place == sim::BearingPlace::Front ? "front" : "rear", f,
                            o.window_h * 3600, true});
          }
        for (int ch : o.open_probe_channels) {
          sim::FaultSpec f;
          f.kind = sim::FaultKind::OpenProbe;
          f.channel = ch;
          jobs.push_back({"open probe", fmt::format("ch{}", ch), f, o.sensor_window_h * 3600, false});
        }
        const std::vector<ChildReport> reps = run_children(jobs.size(), o.jobs, [&](size_t i) {
          return watch_fault(session, module, jobs[i].spec, jobs[i].window_s, jobs[i].stop_at_alarm);
        });
        for (size_t i = 0; i < jobs.size(); ++i) {
          const ChildReport& rep = reps[i];
          FaultRun fr;
          fr.fault = jobs[i].name;
          fr.place = jobs[i].place;
          fr.moment = m;
          fr.state_before = worst_thermal(last);
          fr.window_s = jobs[i].window_s;
          fr.ok = rep.ok != 0;
          fr.error = rep.error;
          fr.warn_s = rep.warn_s, fr.alarm_s = rep.alarm_s, fr.sensor_s = rep.sensor_s;
          fr.warn_channel = rep.warn_channel, fr.alarm_channel = rep.alarm_channel;
          fr.sensor_channel = rep.sensor_channel;
          say(fmt::format("{:>13} {:<5} at {:5.2f} h ({}, {:.0f} rpm): WARN {} min, ALARM {} min (ch{}){}", fr.fault,
                          fr.place, m.t_s / 3600, moment_kind_name(m.kind), m.rpm, minutes(fr.warn_s, fr.window_s),
                          minutes(fr.alarm_s, fr.window_s), fr.alarm_channel,
                          fr.sensor_s >= 0 ? fmt::format(", SENSOR_FAULT {:.2f} min (ch{})", fr.sensor_s / 60, fr.sensor_channel)
                                           : std::string()) +
              (fr.ok ? "" : " -- run failed: " + fr.error));
          res.faults.push_back(fr);
        }
      }
      // Fault-free accounting.
      ++ff.samples;
      if (trace_n++ % 6 == 0) {
        trace << fmt::format("{:.4f},{}", (t - t_prod) / 3600, s.speed_rpm);
        for (int c = 0; c < wire::kChannels; ++c) {
          const auto cell = [](int32_t v) { return v == wire::kMissing ? std::string() : fmt::format("{:.3f}", v / 1000.0); };
          trace << "," << cell(s.temp_mK[c]) << "," << cell(s.predicted_mK[c]) << "," << state_of(s, c);
        }
        trace << "\n";
      }
      bool any_warn = false, any_alarm = false;
      for (int c = 0; c < wire::kChannels; ++c) {
        const int st = state_of(s, c);
        if (st == kWarn && prev[c] == kNormal) {
          ++ff.warn_episodes;
          ff.episodes.push_back(fmt::format("{:.2f} h WARN ch{}", (t - t_prod) / 3600, c + 1));
        }
        if (st == kAlarm && prev[c] != kAlarm) {
          ++ff.alarm_episodes;
          ff.episodes.push_back(fmt::format("{:.2f} h ALARM ch{}", (t - t_prod) / 3600, c + 1));
        }
        any_warn |= st == kWarn;
        any_alarm |= st == kAlarm;
        if (st == kSensorFault) ++ff.sensor_fault_samples;
        prev[c] = st;
      }
      ff.warn_samples += any_warn;
      ff.alarm_samples += any_alarm;
      // The operator acknowledges an ALARM at once, so that a later one is seen as a new episode.
      if (any_alarm && !acked) {
        session.ack_alarm();
        acked = true;
      }
      if (!any_alarm) acked = false;
      if ((t - t_prod) / 3600 >= next_progress_h) {
        say(fmt::format("fault-free run: {:.0f} of {:.0f} h, {} WARN / {} ALARM episodes so far", next_progress_h,
                        ff.hours, ff.warn_episodes, ff.alarm_episodes));
        next_progress_h += 6;
      }
    }
    last = s;
  }

  // --- 3. Results ----------------------------------------------------------------------------------
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  for (int who : {RUSAGE_SELF, RUSAGE_CHILDREN}) {
    struct rusage ru {};
    if (::getrusage(who, &ru) == 0)
      res.cpu_s += double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  }
  std::ofstream csv(fs::path(o.out_dir) / "detection.csv");
  csv << "# btsm detection benchmark, board " << res.board << "; profile: " << res.profile << "\n"
      << "fault,place,moment,moment_h,rpm,state_before,window_min,warn_min,warn_ch,alarm_min,alarm_ch,sensor_fault_min,"
         "sensor_ch,ok\n";
  for (const auto& f : res.faults)
    csv << fmt::format("{},{},{},{:.3f},{:.0f},{},{:.0f},{:.2f},{},{:.2f},{},{:.3f},{},{}\n", f.fault, f.place,
                       moment_kind_name(f.moment.kind), f.moment.t_s / 3600, f.moment.rpm, f.state_before,
                       f.window_s / 60, f.warn_s / 60, f.warn_channel, f.alarm_s / 60, f.alarm_channel,
                       f.sensor_s / 60, f.sensor_channel, f.ok ? 1 : 0);
  return res;
}

std::string DetectionResult::runs_table() const {
  std::string t = fmt::format("{:<13} {:<5} {:<10} {:>7} {:>6} {:>7} {:>9} {:>10} {:>4} {:>13}\n", "fault", "place",
                              "moment", "at (h)", "rpm", "before", "WARN min", "ALARM min", "ch", "SENSOR_FAULT");
  for (const auto& f : faults) {
    const char* before = f.state_before == kAlarm ? "ALARM" : f.state_before == kWarn ? "WARN" : "normal";
    t += fmt::format("{:<13} {:<5} {:<10} {:>7.2f} {:>6.0f} {:>7} {:>9} {:>10} {:>4} {:>13}{}\n", f.fault, f.place,
                     moment_kind_name(f.moment.kind), f.moment.t_s / 3600, f.moment.rpm, before,
                     minutes(f.warn_s, f.window_s), minutes(f.alarm_s, f.window_s),
                     f.alarm_channel ? fmt::format("{}", f.alarm_channel) : std::string("-"),
                     f.sensor_s < 0 ? std::string("-") : fmt::format("{:.2f} min ch{}", f.sensor_s / 60, f.sensor_channel),
                     f.ok ? "" : "  FAILED: " + f.error);
  }
  return t;
}

std::string DetectionResult::summary_table() const {
  struct Group {
    std::vector<double> warn, alarm, sensor;
    int runs = 0;
    double window_s = 0;
    std::set<int> channels;
  };
  std::vector<std::pair<std::string, std::string>> order;
  std::map<std::pair<std::string, std::string>, Group> groups;
  int started_in_warn = 0;
  for (const auto& f : faults) {
    const auto k = std::make_pair(f.fault, f.place);
    if (!groups.count(k)) order.push_back(k);
    Group& g = groups[k];
    g.window_s = f.window_s;
    // A run that starts in WARN (a false WARN of the fault-free history) says nothing about the
    // time to WARN or ALARM: it is left out of the figures (and counted below the table).
    if (f.state_before != kNormal) {
      ++started_in_warn;
      continue;
    }
    ++g.runs;
    if (f.warn_s >= 0) g.warn.push_back(f.warn_s);
    if (f.alarm_s >= 0) g.alarm.push_back(f.alarm_s), g.channels.insert(f.alarm_channel);
    if (f.sensor_s >= 0) g.sensor.push_back(f.sensor_s), g.channels.insert(f.sensor_channel);
  }
  auto stat = [](std::vector<double> v, int runs, double window_s) {
    if (runs == 0) return std::string("no run");
    if (v.empty()) return fmt::format("none in {:.0f} (0/{})", window_s / 60, runs);
    std::sort(v.begin(), v.end());
    const double med = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
    return fmt::format("{:.1f} [{:.1f}-{:.1f}] {}/{}", med / 60, v.front() / 60, v.back() / 60, v.size(), runs);
  };
  std::string t = fmt::format("{:<13} {:<5} {:>22} {:>22} {:>22}  {}\n", "fault", "place", "to WARN (min)",
                              "to ALARM (min)", "to SENSOR_FAULT (min)", "channel");
  for (const auto& k : order) {
    const Group& g = groups[k];
    std::string ch;
    for (int c : g.channels) ch += (ch.empty() ? "" : ", ") + std::string(kChannelNames[c - 1]);
    t += fmt::format("{:<13} {:<5} {:>22} {:>22} {:>22}  {}\n", k.first, k.second, stat(g.warn, g.runs, g.window_s),
                     stat(g.alarm, g.runs, g.window_s), g.sensor.empty() ? std::string("-") : stat(g.sensor, g.runs, g.window_s),
                     ch.empty() ? "-" : ch);
  }
  t += "times: median [fastest-slowest] runs with the state/runs, module time from the fault's start to the first\n"
       "SAMPLE showing it";
  t += started_in_warn ? fmt::format("; {} runs left out: the module was already in WARN or ALARM\n", started_in_warn)
                       : std::string("\n");
  return t;
}

std::string DetectionResult::fault_free_line() const {
  const FaultFreeRun& f = fault_free;
  std::string s = fmt::format("fault-free {:.0f} h ({} samples): {} WARN episodes, {} ALARM episodes ({} / {} samples "
                              "in WARN / ALARM, {} in SENSOR_FAULT)",
                              f.hours, f.samples, f.warn_episodes, f.alarm_episodes, f.warn_samples, f.alarm_samples,
                              f.sensor_fault_samples);
  for (size_t i = 0; i < f.episodes.size() && i < 12; ++i) s += (i ? ", " : ": ") + f.episodes[i];
  if (f.episodes.size() > 12) s += fmt::format(", ... ({} in all)", f.episodes.size());
  return s;
}

}  // namespace btsm::bench
