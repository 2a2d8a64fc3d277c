#include "host/link/recorder.hpp"

#include "host/io/output_file.hpp"
#include "host/thermal/recording.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace btsm::link {

using namespace btsm::wire;

int ChannelRoles::ambient_index() const {
  for (int i = 0; i < kChannels; ++i)
    if (role[i] == static_cast<uint8_t>(ChannelRole::Ambient)) return i;
  return -1;
}

std::string ChannelRoles::describe() const {
  std::string s;
  for (int i = 0; i < kChannels; ++i) {
    const char* n = channel_role_name(role[i]);
    s += fmt::format("{}T{}={}", i ? "," : "", i + 1, n ? n : "unknown");
  }
  return s + (from_module ? "" : " (firmware defaults, not read from the module)");
}

ChannelRoles read_channel_roles(Session& session) {
  ChannelRoles r;
  for (uint8_t i = 0; i < kChannels; ++i) r.role[i] = static_cast<uint8_t>(default_channel_role(i));
  try {
    for (uint8_t i = 0; i < kChannels; ++i)
      r.role[i] = static_cast<uint8_t>(session.get_config(channel_role_key(i)).value);
    r.from_module = true;
  } catch (const NackError& e) {
    if (e.code() != static_cast<uint8_t>(Nack::UnknownType)) throw;  // firmware without GET_CONFIG
    for (uint8_t i = 0; i < kChannels; ++i) r.role[i] = static_cast<uint8_t>(default_channel_role(i));
  }
  return r;
}

double mk_to_c(int32_t mk) { return mk == kMissing ? std::nan("") : mk / 1000.0; }

std::string firmware_version(const Info& info) {
  return fmt::format("{}.{}.{}", info.fw_major, info.fw_minor, info.fw_patch);
}

ModuleIdentity identify(Session& session) {
  ModuleIdentity id;
  id.info = session.get_info();
  id.roles = read_channel_roles(session);
  id.link = session.transport().describe();
  return id;
}

std::optional<SampleEvent> next_sample_with_reconnect(Session& session, Millis timeout, double reconnect_s,
                                                      uint64_t& reconnects, const std::atomic<bool>* stop,
                                                      const LinkLossNotes* notes) {
  try {
    return session.next_sample(timeout);
  } catch (const LinkError& e) {
    if (e.kind() != LinkErrorKind::kDeviceGone || reconnect_s <= 0) throw;
    const auto lost_at = std::chrono::steady_clock::now();
    const auto give_up = lost_at + std::chrono::duration<double>(reconnect_s);
    std::string last = e.what();
    if (notes && notes->lost) notes->lost(last, reconnect_s);
    while (std::chrono::steady_clock::now() < give_up) {
      if (stop && stop->load()) return std::nullopt;
      std::this_thread::sleep_for(Millis(500));
      try {
        session.transport().reopen();
        session.resync();
        ++reconnects;
        if (notes && notes->back)
          notes->back(std::chrono::duration<double>(std::chrono::steady_clock::now() - lost_at).count());
        return std::nullopt;  // the caller loops; the tracker reports what was lost meanwhile
      } catch (const LinkError& again) {
        last = again.what();
      }
    }
    throw LinkError(LinkErrorKind::kDeviceGone,
                    fmt::format("link lost and not back within {:.0f} s: {}", reconnect_s, last));
  }
}

std::string sensor_fault_code(uint8_t st) {
  std::string code;
  auto add = [&](uint8_t bit, const char* name) {
    if (st & bit) code += (code.empty() ? "" : "+") + std::string(name);
  };
  add(kFaultOpen, "open");
  add(kFaultShort, "short");
  add(kFaultAdc, "adc");
  add(kFaultReference, "ref");
  if (code.empty() && (st & kStatusStateMask) == static_cast<uint8_t>(DiagState::SensorFault)) code = "fault";
  return code;
}

namespace {

// Per channel, the stretch of rows with one fault code; closed when the code changes.
class SensorFaultEpisodes {
 public:
  void row(double time_s, const Sample& s, const ChannelRoles& roles) {
    for (int c = 0; c < kChannels; ++c) {
      if (roles.role[c] == static_cast<uint8_t>(ChannelRole::Disabled)) continue;
      const std::string code = sensor_fault_code(s.channel_status[c]);
      Open& o = open_[c];
      if (!o.code.empty() && o.code != code) close(c);
      if (!code.empty() && o.code.empty()) o = Open{code, time_s, time_s};
      if (!code.empty()) o.last_s = time_s;
    }
  }
  std::vector<thermal::SensorFaultEpisode> finish() {
    for (int c = 0; c < kChannels; ++c)
      if (!open_[c].code.empty()) close(c);
    return done_;
  }

 private:
  struct Open {
    std::string code;
    double first_s = 0, last_s = 0;
  };
  void close(int c) {
    done_.push_back({fmt::format("T{}", c + 1), open_[c].code, open_[c].first_s, open_[c].last_s});
    open_[c] = Open{};
  }
  Open open_[kChannels];
  std::vector<thermal::SensorFaultEpisode> done_;
};

// The summary lines after the rows, through the output helper as the rows were: the file is
// reopened by its name, and whatever stands there now is written only if it is a regular file.
void append_to_recording(const std::string& path, const std::string& text) {
  std::FILE* f = io::open_output_stream(path, "recording", true);
  const bool written = std::fputs(text.c_str(), f) >= 0;
  if (std::fclose(f) != 0 || !written) throw std::runtime_error("cannot append the summary to " + path + ": " + std::strerror(errno));
}

}  // namespace

RecordSummary record(Session& session, const ModuleIdentity& id, const RecordOptions& opts) {
  RecordSummary sum;
  // Two channels with one measured role (or two ambients) make a recording every reader refuses
  // (recording_metadata.hpp): say so before hours are recorded.
  for (int a = 0; a < kChannels; ++a)
    for (int b = a + 1; b < kChannels; ++b) {
      const uint8_t r = id.roles.role[a];
      if (r != id.roles.role[b] || !(is_thermal_role(r) || r == static_cast<uint8_t>(ChannelRole::Ambient))) continue;
      throw std::invalid_argument(fmt::format("channels {} and {} both have the role {}: a role belongs to one channel "
                                              "(set one of them with `btsm set-config channel_role_N ROLE`)",
                                              a + 1, b + 1, channel_role_name(r)));
    }
  const int amb = id.roles.ambient_index();
  if (amb < 0)
    throw std::runtime_error("no channel has the ambient role, so ambient_c cannot be recorded: set one with "
                             "`btsm set-config channel_role_N ambient`");
  std::vector<int> columns;
  std::vector<std::string> names;
  for (int i = 0; i < kChannels; ++i) {
    if (i == amb || id.roles.role[i] == static_cast<uint8_t>(ChannelRole::Disabled)) continue;
    columns.push_back(i);
    names.push_back(fmt::format("T{}", i + 1));
  }

  thermal::RecordingWriter w;
  w.open(opts.out_path, names);
  w.write_meta("source", opts.source_label);
  w.write_meta("module_id", fmt::format("{:08x}", id.info.device_id));
  w.write_meta("firmware_version", firmware_version(id.info));
  w.write_meta("protocol_version", std::to_string(id.info.protocol_version));
  w.write_meta("link", id.link);
  w.write_meta("channel_roles", id.roles.describe());
  w.write_meta("ambient_channel", fmt::format("T{}", amb + 1));
  w.write_meta("model_crc", fmt::format("{:08x}", id.info.model_crc));
  w.write_meta("time_base", "module time_ms since the first sample, s");

  // The silence that means "module stopped" depends on its sample period (1 s .. 10 min).
  double period_guess_s = 5.0;
  try {
    period_guess_s = session.get_config(static_cast<uint8_t>(ConfigKey::SamplePeriodMs)).value / 1000.0;
    w.write_meta("sample_period_s", fmt::format("{:g}", period_guess_s));
  } catch (const NackError&) {
    // older firmware without GET_CONFIG: keep the default guess
  }
  const double sample_timeout_s = opts.sample_timeout_s > 0 ? opts.sample_timeout_s : 3 * period_guess_s + 10;
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<uint32_t> last_ms;
  double epoch_base_s = 0, last_time_s = -1;
  uint64_t epoch_ms = 0;
  auto last_rx = std::chrono::steady_clock::now();
  auto last_host = last_rx;
  double last_ambient = std::nan("");

  // The rows already written are good whatever ends the recording: a lost link still gets the
  // summary lines (with the reason), then the error goes to the caller.
  SensorFaultEpisodes faults;
  const auto finish = [&] {
    sum.lost = session.tracker().lost();
    sum.sensor_faults = faults.finish();
    sum.invalid_frames = session.frame_counters().frame_errors() + session.invalid_payloads();
    w.flush();
    w.close();
    // RecordingWriter takes metadata only before the first row, and gaps are only known as they
    // happen, so the summary goes after the rows as comment lines (the reader accepts '#' lines
    // anywhere).
    std::ostringstream tail;
    tail << "# samples: " << sum.rows << "\n";
    tail << "# lost_samples: " << sum.lost << "\n";
    tail << "# module_restarts: " << sum.restarts << "\n";
    tail << "# link_reconnects: " << sum.reconnects << "\n";
    tail << "# rejected_frames: " << sum.invalid_frames << "\n";
    if (sum.ambient_held_rows) tail << "# ambient_held_rows: " << sum.ambient_held_rows << "\n";
    if (sum.rows_without_ambient) tail << "# rows_without_ambient: " << sum.rows_without_ambient << "\n";
    for (const auto& g : sum.gaps) tail << "# dropped: " << g.first << "-" << g.last << "\n";
    for (const auto& f : sum.sensor_faults)
      tail << "# " << thermal::kSensorFaultKey << ": " << thermal::format_sensor_fault(f) << "\n";
    tail << "# stop_reason: " << sum.stop_reason << "\n";
    append_to_recording(opts.out_path, tail.str());
  };
  try {
    for (;;) {
      if (opts.stop && opts.stop->load()) {
        sum.stop_reason = "interrupted";
        break;
      }
      if (opts.max_samples && sum.rows >= opts.max_samples) {
        sum.stop_reason = "sample count reached";
        break;
      }
      if (opts.duration_s > 0 && last_time_s >= opts.duration_s) {
        sum.stop_reason = "duration reached";
        break;
      }
      auto ev = next_sample_with_reconnect(session, Millis(250), opts.reconnect_s, sum.reconnects, opts.stop,
                                           &opts.link_notes);
      const auto now = std::chrono::steady_clock::now();
      if (!ev) {
        if (std::chrono::duration<double>(now - last_rx).count() > sample_timeout_s)
          throw LinkError(LinkErrorKind::kTimeout,
                          fmt::format("{}: no sample for {:.0f} s (module stopped sending?)",
                                      session.transport().describe(), sample_timeout_s));
        continue;
      }
      last_rx = now;
      const Sample& s = ev->sample;
      // Module time, unwrapped across the u32 wrap by summing per-sample differences in integer
      // ms; a restart starts a new epoch placed after the last row by the host clock.
      if (!last_ms) {
        epoch_base_s = 0;
        epoch_ms = 0;
      } else if (ev->restarted) {
        ++sum.restarts;
        epoch_base_s = last_time_s + std::max(0.001, std::chrono::duration<double>(now - last_host).count());
        epoch_ms = 0;
      } else {
        epoch_ms += static_cast<uint32_t>(s.time_ms - *last_ms);
      }
      last_ms = s.time_ms;
      last_host = now;
      const double time_s = epoch_base_s + static_cast<double>(epoch_ms) / 1000.0;
      if (ev->gap) sum.gaps.push_back(*ev->gap);

      double ambient = mk_to_c(s.temp_mK[amb]);
      if (std::isnan(ambient)) {
        if (std::isnan(last_ambient)) {
          ++sum.rows_without_ambient;
          continue;
        }
        ambient = last_ambient;
        ++sum.ambient_held_rows;
      }
      last_ambient = ambient;
      if (time_s <= last_time_s) continue;  // never write non-increasing time (duplicate timestamp)
      std::vector<double> temps;
      for (int c : columns) temps.push_back(mk_to_c(s.temp_mK[c]));
      w.append(time_s, s.speed_rpm, ambient, temps);
      w.flush();  // every row on disk as it comes: a killed `record` loses nothing it showed, and a full disk fails now
      faults.row(time_s, s, id.roles);
      last_time_s = time_s;
      ++sum.rows;
      if (opts.progress) {
        RecordProgress p;
        p.rows = sum.rows;
        p.lost = session.tracker().lost();
        p.restarts = sum.restarts;
        p.elapsed_s = std::chrono::duration<double>(now - t0).count();
        p.module_time_s = time_s;
        p.last = &s;
        opts.progress(p);
      }
    }
  } catch (const LinkError& e) {
    sum.stop_reason = std::string("link lost: ") + e.what();
    finish();
    throw;
  }
  finish();
  return sum;
}

std::string format_sample_line(const Sample& s, const ChannelRoles& roles) {
  std::string line = fmt::format("#{:<7} {:>5} rpm ", s.sample_index, s.speed_rpm);
  for (int i = 0; i < kChannels; ++i) {
    if (roles.role[i] == static_cast<uint8_t>(ChannelRole::Disabled)) continue;
    const double t = mk_to_c(s.temp_mK[i]);
    const double p = mk_to_c(s.predicted_mK[i]);
    line += fmt::format("| T{} ", i + 1);
    line += std::isnan(t) ? std::string("   --   ") : fmt::format("{:7.3f}", t);
    if (!std::isnan(p)) line += fmt::format(" (pred {:7.3f})", p);
    const uint8_t st = s.channel_status[i];
    if ((st & kStatusStateMask) != 0 || (st & ~kStatusStateMask) != 0) {
      line += std::string(" ") + diag_state_name(st);
      if (st & kFaultOpen) line += "/open";
      if (st & kFaultShort) line += "/short";
      if (st & kFaultAdc) line += "/adc";
      if (st & kFaultReference) line += "/ref";
      // The filter held its estimate against this reading (an outlier): the temperature shown is
      // the estimate, and the technician should know a probe is jumping.
      if (st & kFaultKalmanReject) line += "/outlier";
    }
    line += " ";
  }
  line += fmt::format("| {}", diag_state_name(s.overall));
  if (s.overall & kOverallAlarmLatched) line += " LATCHED";
  if (s.overall & kOverallModelActive) line += " model";
  return line;
}

}  // namespace btsm::link
